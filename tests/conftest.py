"""Session-wide test settings."""

import pytest


@pytest.fixture(autouse=True, scope="session")
def _isolated_cache(tmp_path_factory):
    # On-disk caches (capacitive meshes) go to a fresh directory, so the tests
    # neither read a user's cache nor leave files in it, and every run starts cold.
    mp = pytest.MonkeyPatch()
    mp.setenv("TWINSENSE_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))
    yield
    mp.undo()
