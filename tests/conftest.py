"""Fixtures shared by the whole test suite."""

from __future__ import annotations

from pathlib import Path

import pytest

# The repository sits beside shared/ (…/main and …/shared), both in a developer's work tree
# and in CI's fresh clone.
SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.fixture(scope="session")
def bandai_root() -> Path:
    """The Bandai Namco Research Motion Dataset folder (dataset-1/, dataset-2/); skips when absent."""
    root = SHARED_DATA / "bandai"
    if not root.is_dir():
        pytest.skip(f"the shared Bandai data is not at {root}")
    return root


@pytest.fixture
def one_torch_thread():
    """One torch thread: faster for tiny networks and fair on a shared machine. Test files
    that build networks use it for every test (``pytestmark``)."""
    import torch

    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)
