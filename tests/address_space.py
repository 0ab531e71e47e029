"""An address-space limit for tests that must stay O(N) in memory: RLIMIT_AS (soft) at the
process's own virtual size when the block starts plus a budget, restored afterwards, so it
bounds what the block adds whatever the session loaded before."""

import contextlib
import resource

BUDGET = 1 << 30
"""Bytes of address space a block may add by default."""


def virtual_size() -> int:
    """This process's virtual size in bytes (VmSize)."""
    with open("/proc/self/status") as f:
        return next(int(x.split()[1]) for x in f if x.startswith("VmSize:")) * 1024


@contextlib.contextmanager
def address_space_limit(budget: int = BUDGET):
    """RLIMIT_AS (soft) at the current virtual size + ``budget`` inside the block."""
    old = resource.getrlimit(resource.RLIMIT_AS)
    soft = virtual_size() + budget
    if old[1] != resource.RLIM_INFINITY:
        soft = min(soft, old[1])
    resource.setrlimit(resource.RLIMIT_AS, (soft, old[1]))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, old)
