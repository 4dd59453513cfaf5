"""Test session setup: import dualarm before any test imports MuJoCo, so that on a headless
machine MuJoCo's OpenGL backend is EGL (``dualarm/__init__`` chooses it; MuJoCo reads the
choice when it is first imported)."""

import dualarm  # noqa: F401

import pytest  # noqa: E402


def pytest_addoption(parser):
    parser.addoption("--paper-scale", action="store_true",
                     help="also run the tests marked paper_scale (training runs of tens of minutes)")


def pytest_configure(config):
    config.addinivalue_line("markers", "slow(minutes=0.5): minutes of training or hundreds of episodes, "
                            "about `minutes` long on 2 vCPUs; CI runs them (the longest first), the "
                            "quick loop leaves them out (pytest -m 'not slow')")
    config.addinivalue_line("markers", "paper_scale: a training run of tens of minutes; only with "
                            "--paper-scale (CI skips it)")
    # pytest-xdist's default schedule hands each worker a run of consecutive tests (a quarter of
    # its share) to start with: all the long tests, sorted first below, would land on one
    # worker. Two at a time deals them out, one worker each, while the quick ones fill in.
    if config.pluginmanager.hasplugin("xdist") and getattr(config.option, "maxschedchunk", 0) is None:
        config.option.maxschedchunk = 2


def expected_minutes(item) -> float:
    """A test's expected length in minutes from its marker: paper_scale tens, slow(minutes=M)
    M (a bare slow 0.5), any other 0."""
    if "paper_scale" in item.keywords:
        return 30.0
    slow = item.get_closest_marker("slow")
    return 0.0 if slow is None else float(slow.kwargs.get("minutes", 0.5))


def pytest_collection_modifyitems(config, items):
    # The longest tests first (a stable sort keeps every other order): with `-n` (pytest-xdist,
    # two tests at a time per worker, above) they start at once on different workers instead
    # of ending the run alone. No test depends on the order.
    items.sort(key=lambda item: -expected_minutes(item))
    if config.getoption("--paper-scale"):
        return
    skip = pytest.mark.skip(reason="paper scale: run with --paper-scale")
    for item in items:
        if "paper_scale" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="module")
def shipped():
    """The shipped demonstration folder as replays read it, with an environment to replay in:
    (env, recordings, labels by name, scenes by name)."""
    from dualarm.demos.formats import DEFAULT_DEMO_DIR
    from dualarm.envs import make_core
    from dualarm.sim_demos.replay import load_replay_folder

    env = make_core()
    demos, labels, scenes = load_replay_folder(DEFAULT_DEMO_DIR, env.config.workspace())
    yield env, demos, labels, scenes
    env.close()
