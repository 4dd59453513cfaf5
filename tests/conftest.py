"""Test session setup: import dualarm before any test imports MuJoCo, so that on a headless
machine MuJoCo's OpenGL backend is EGL (``dualarm/__init__`` chooses it; MuJoCo reads the
choice when it is first imported)."""

import dualarm  # noqa: F401
