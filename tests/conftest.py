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
