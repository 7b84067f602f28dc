"""Random streams: one per (seed, purpose, index), never shared between different keys."""

import math

import numpy as np
import pytest

from lensmount.physics.sampler import stream


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


def test_streams_depend_only_on_their_keys():
    from lensmount.physics.sampler import Streams

    ids = np.arange(1000, 3000)
    whole = Streams(3, "forward", ids, step=2)
    part = Streams(3, "forward", ids[500:700], step=2)  # the same photons in another batch
    np.testing.assert_array_equal(whole.at(np.arange(500, 700), 5), part.at(None, 5))
    np.testing.assert_array_equal(whole.take(slice(500, 700)).at(None, 5), part.at(None, 5))
    for other in (Streams(4, "forward", ids, step=2), Streams(3, "photons", ids, step=2),
                  Streams(3, "forward", ids, step=3)):
        assert not np.any(other.at(None, 5) == whole.at(None, 5))
    a, b = Streams(1, "x", (np.arange(10), 2)).random((10, 3)), Streams(1, "x", (np.arange(10), 2)).random((10, 3))
    np.testing.assert_array_equal(a, b)  # tuple keys hash the same every time


def test_streams_are_uniform_and_uncorrelated():
    """Moments of U(0,1) and no correlation between neighbouring photons, dimensions or steps
    (tolerances at ~5 standard errors for 200 000 draws)."""
    from lensmount.physics.sampler import Streams

    n = 200_000
    s = Streams(1, "test", np.arange(n), step=0)
    u, v, w = s.at(None, 0), s.at(None, 1), Streams(1, "test", np.arange(n), step=1).at(None, 0)
    assert np.all((u >= 0) & (u < 1))
    assert abs(u.mean() - 0.5) < 5 * math.sqrt(1 / 12 / n)
    assert abs(u.var() - 1 / 12) < 5 * math.sqrt((1 / 80 - 1 / 144) / n)  # SE of a sample variance: (μ4 − σ⁴)/n
    hist = np.bincount((u * 20).astype(int), minlength=20)
    assert np.abs(hist - n / 20).max() < 5 * math.sqrt(n / 20)
    for x, y in ((u, v), (u, w), (u[:-1], u[1:])):
        assert abs(np.corrcoef(x, y)[0, 1]) < 5 / math.sqrt(n)
