"""fraytool: woven cloth that tears with frayed edges, simulated at yarn level and rendered headless.

Method: N. Metaaphanon, Y. Bando, B.-Y. Chen, T. Nishita, "Simulation of Tearing Cloth with Frayed
Edges", Pacific Graphics 2009 (restated in our words in docs/method.md).

Python API (see README):

    from fraytool.scene import load_scene
    from fraytool.sim import build_model, SolverExplicitPBD
"""
__version__ = "0.1.0"

from pathlib import Path as _Path

from fraytool._numba_cache import invalidate_stale_numba_cache as _invalidate

_invalidate(_Path(__file__).parent)  # before any cached numba kernel is loaded
