import contextlib
import os

import pytest


@contextlib.contextmanager
def _environ(name: str, value: str):
    """``os.environ[name] = value`` for the block, then as it was."""
    old = os.environ.get(name)
    os.environ[name] = value
    try:
        yield
    finally:
        if old is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = old


@pytest.fixture(autouse=True, scope="session")
def _map_cache_in_a_temporary_folder(tmp_path_factory):
    """Mapping-run maps are cached on disk: tests write to a fresh folder, never to ~/.cache."""
    with _environ("SEMRELOC_CACHE_DIR", str(tmp_path_factory.mktemp("semreloc_cache"))):
        yield


@pytest.fixture(autouse=True, scope="session")
def _sb3_logs_in_a_temporary_folder(tmp_path_factory):
    """SB3 makes an empty ``SB3-<time>`` folder under the system's temp dir for every model that learns without a
    logger of its own (``configure(None)``; `agents.train` sets one): tests give it a folder of theirs instead."""
    with _environ("SB3_LOGDIR", str(tmp_path_factory.mktemp("sb3_logs"))):
        yield
