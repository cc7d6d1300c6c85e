"""numba kernels of the solver. Each takes arrays and scalars only, never objects (docs/architecture.md).

Every kernel is compiled lazily, on its first call, and cached on disk (cache=True), so a scene
that has no rigid bodies never compiles the rigid-contact kernel, and a second run starts fast.
"""
