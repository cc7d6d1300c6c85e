"""fraytool: woven cloth that tears with frayed edges, simulated at yarn level and rendered headless.

Method: N. Metaaphanon, Y. Bando, B.-Y. Chen, T. Nishita, "Simulation of Tearing Cloth with Frayed
Edges", Pacific Graphics 2009 (restated in docs and in ../shared/paper/METHOD.md).

Python API (see README):

    from fraytool.scene import load_scene
    from fraytool.sim import build_model, SolverExplicitPBD
"""
__version__ = "0.1.0"
