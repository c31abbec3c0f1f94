"""The global test seed: COHERENT_TEST_SEED (default 0) offsets the seeds of
statistical tests, as tests/native/test_seed.h does for the native suite.
(The helper is not named test_*: pytest would collect it where imported.)"""

import os

STRIDE = 1000003


def global_seed_offset():
    return int(os.environ.get("COHERENT_TEST_SEED", "0") or 0)


def seeded(base):
    """`base` moved by the global offset."""
    return base + global_seed_offset() * STRIDE
