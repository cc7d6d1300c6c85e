"""The one place that creates an OpenGL context: headless EGL through moderngl.

Works on a server with no display and no GPU (Mesa's llvmpipe software rasteriser). The CLI, the
benchmark and the test suite's session fixture (tests/conftest.py) all call `create_context`; no
other code creates contexts. If none can be made the caller gets a RunError (exit code 1) saying
what to install and which environment variables to check, never a traceback.
"""
from __future__ import annotations

import os

import moderngl

from fraytool.errors import RunError

REQUIRED_GL_VERSION = 330
"""Shaders are GLSL 3.30 core."""

_HINT = (
    "fraytool renders headless through EGL (no display or GPU needed, Mesa's llvmpipe is enough).\n"
    "Check that the system packages libegl1 and libgl1-mesa-dri are installed "
    "(Debian/Ubuntu: apt-get install libegl1 libgl1-mesa-dri; Fedora: mesa-libEGL mesa-dri-drivers),\n"
    "and the environment: EGL_PLATFORM=surfaceless selects display-less EGL; "
    "LIBGL_ALWAYS_SOFTWARE=1 and MESA_LOADER_DRIVER_OVERRIDE=llvmpipe force the software renderer; "
    "an unset or wrong __EGL_VENDOR_LIBRARY_FILENAMES / LIBGL_DRIVERS_PATH can hide the Mesa driver."
)


def _env_summary() -> str:
    keys = ("EGL_PLATFORM", "LIBGL_ALWAYS_SOFTWARE", "MESA_LOADER_DRIVER_OVERRIDE", "GALLIUM_DRIVER",
            "__EGL_VENDOR_LIBRARY_FILENAMES", "LIBGL_DRIVERS_PATH")
    shown = [f"{k}={os.environ[k]}" for k in keys if k in os.environ]
    return "current environment: " + (", ".join(shown) if shown else "none of these is set")


def create_context() -> moderngl.Context:
    """A standalone (off-screen) moderngl context through EGL, OpenGL 3.3 core or newer."""
    try:
        ctx = moderngl.create_context(standalone=True, backend="egl", require=REQUIRED_GL_VERSION)
    except Exception as exc:  # moderngl/glcontext raise plain Exceptions with the EGL error text
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise RunError(f"cannot create an OpenGL context through EGL: {reason}\n{_HINT}\n{_env_summary()}") from None
    return ctx


def gl_strings(ctx: moderngl.Context) -> str:
    """GL_RENDERER and GL_VERSION on one line (part of the render reuse key: fraytool.render.job)."""
    info = ctx.info
    return f"{info.get('GL_RENDERER', '?')}; {info.get('GL_VERSION', '?')}"


def describe(ctx: moderngl.Context) -> str:
    """Two lines naming the renderer and the GL version (for `fraytool render -v`)."""
    info = ctx.info
    return (f"GL_RENDERER: {info.get('GL_RENDERER', '?')}\n"
            f"GL_VERSION: {info.get('GL_VERSION', '?')} (max samples {ctx.max_samples})")


def check_gl_error(ctx: moderngl.Context, where: str) -> None:
    """Raise RunError if the GL error flag is set (glGetError), naming the step that set it."""
    err = ctx.error
    if err != "GL_NO_ERROR":
        raise RunError(f"OpenGL error after {where}: {err}")
