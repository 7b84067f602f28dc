"""Random streams: one per (seed, purpose, index), never shared between different keys."""

import numpy as np
import pytest

from lensmount.trace.sampler import stream


def test_same_key_same_numbers_and_different_keys_differ():
    assert np.array_equal(stream(7, "photons", 3).random(5), stream(7, "photons", 3).random(5))
    draws = {tuple(stream(s, p, i).random(3)) for s in (1, 2) for p in ("photons", "view-map") for i in (0, 1)}
    assert len(draws) == 8


def test_seeds_are_not_folded_to_32_bits():
    """Review finding: seed 1 and 2**32 + 1 used to give the same stream."""
    assert not np.array_equal(stream(1, "photons").random(4), stream(2**32 + 1, "photons").random(4))


def test_negative_seed_is_refused():
    with pytest.raises(ValueError):
        stream(-1, "photons")
