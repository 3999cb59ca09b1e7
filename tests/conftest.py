import os
import sys
from pathlib import Path

import pytest
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

REFERENCE_DIR = Path(os.environ.get("MORL_TRL_REFERENCE", ROOT.parent / "shared" / "reference"))


@pytest.fixture(scope="session")
def reference_dir() -> Path:
    """The published reference data (../shared/reference); tests using it skip without it."""
    if not (REFERENCE_DIR / "minmax_values").is_dir():
        pytest.skip(f"reference data not found at {REFERENCE_DIR} (set MORL_TRL_REFERENCE to its path)")
    return REFERENCE_DIR


@pytest.fixture
def single_thread():
    """One intra-op thread for the test (tiny networks: more threads only add contention on a
    shared CPU); the previous count is restored after it."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)
