import os

import pytest


@pytest.fixture(autouse=True, scope="session")
def _map_cache_in_a_temporary_folder(tmp_path_factory):
    """Mapping-run maps are cached on disk: tests write to a fresh folder, never to ~/.cache."""
    old = os.environ.get("SEMRELOC_CACHE_DIR")
    os.environ["SEMRELOC_CACHE_DIR"] = str(tmp_path_factory.mktemp("semreloc_cache"))
    yield
    if old is None:
        del os.environ["SEMRELOC_CACHE_DIR"]
    else:
        os.environ["SEMRELOC_CACHE_DIR"] = old


@pytest.fixture(autouse=True, scope="session")
def _sb3_logs_in_a_temporary_folder(tmp_path_factory):
    """SB3 makes an empty ``SB3-<time>`` folder under the system's temp dir for every model that learns without a
    logger of its own (``configure(None)``; `agents.train` sets one): tests give it a folder of theirs instead."""
    old = os.environ.get("SB3_LOGDIR")
    os.environ["SB3_LOGDIR"] = str(tmp_path_factory.mktemp("sb3_logs"))
    yield
    if old is None:
        del os.environ["SB3_LOGDIR"]
    else:
        os.environ["SB3_LOGDIR"] = old
