"""Test session setup: import dualarm before any test imports MuJoCo, so that on a headless
machine MuJoCo's OpenGL backend is EGL (``dualarm/__init__`` chooses it; MuJoCo reads the
choice when it is first imported)."""

import dualarm  # noqa: F401

import pytest  # noqa: E402


def pytest_addoption(parser):
    parser.addoption("--slow", action="store_true",
                     help="also run the tests marked slow (training runs of tens of minutes)")


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: a training run of tens of minutes; runs with --slow")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--slow"):
        return
    skip = pytest.mark.skip(reason="slow: run with --slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)
