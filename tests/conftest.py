import os

os.environ.setdefault("MPLBACKEND", "Agg")

import pytest  # noqa: E402

from pendsweep.backends import make_backend  # noqa: E402


@pytest.fixture(scope="session")
def emulated():
    return make_backend("emulated")
