"""The grid's k nearest against scipy's cKDTree (the search it replaced) and a brute-force sort."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from lensmount.integrators.photon_mapping.neighbours import FEW_POINTS, _k_nearest, _k_nearest_grouped, k_nearest, kth_distance

# Both searches, whichever k_nearest would pick for the cloud's size.
SEARCHES = {"grid": lambda p, q, k: _k_nearest(p, q, k, 2.0), "grouped": lambda p, q, k: _k_nearest_grouped(p, q, k, 32.0)}


def _brute(points, queries, k):
    """The k smallest by (squared distance summed as cKDTree sums it, index): the rule on ties."""
    diff = queries[:, None, :] - points[None, :, :]
    d2 = (diff[..., 0] * diff[..., 0] + diff[..., 1] * diff[..., 1]) + diff[..., 2] * diff[..., 2]
    order = np.lexsort((np.broadcast_to(np.arange(len(points)), d2.shape), d2), axis=-1)[:, :k]
    return np.sqrt(np.take_along_axis(d2, order, axis=1)), order


def _clouds():
    rng = np.random.default_rng(3)
    t = rng.uniform(size=300)
    sheet = rng.uniform(size=(3000, 3)) * [60.0, 60.0, 0.0] + [0.0, 0.0, 190.0]
    ring = np.stack([30 * np.cos(t * 2 * np.pi), 30 * np.sin(t * 2 * np.pi), np.full_like(t, 5.0)], axis=1)
    crowd = np.concatenate([rng.normal(size=(2000, 3)) * 0.01, rng.normal(size=(200, 3)) * 50.0])
    return {
        "gaussian": rng.normal(size=(2000, 3)),
        "flat sheet": sheet,
        "circle": ring,
        "crowded": crowd,
        "line": np.stack([t, 2 * t, -3 * t], axis=1),
        "huge": rng.normal(size=(1500, 3)) * 1e8 + 1e12,
        "tiny": rng.normal(size=(1500, 3)) * 1e-9,
        "duplicates": np.repeat(rng.normal(size=(60, 3)), 5, axis=0),
        "lattice": np.round(rng.uniform(size=(1500, 3)) * 5.0),
        "one point": rng.normal(size=(1, 3)),
    }


@pytest.mark.parametrize("name", list(_clouds()))
def test_kth_distance_is_the_kd_trees_to_the_bit(name):
    points = _clouds()[name]
    k = min(9, len(points))
    assert np.array_equal(kth_distance(points, points, k), cKDTree(points).query(points, k=[k])[0][:, 0])


@pytest.mark.parametrize("search", list(SEARCHES))
@pytest.mark.parametrize("name", list(_clouds()))
def test_k_nearest_are_the_kd_trees_and_ties_go_to_the_smaller_index(name, search):
    points = _clouds()[name]
    rng = np.random.default_rng(5)
    lo, hi = points.min(axis=0), points.max(axis=0)
    span = np.maximum(hi - lo, 1e-300)
    # Queries inside, around and far outside the cloud (the grid clamps them to its border cells).
    queries = np.concatenate([points[:200], lo + span * rng.uniform(-2.0, 3.0, size=(200, 3))])
    k = min(24, len(points))
    d2, idx = SEARCHES[search](np.ascontiguousarray(points), queries, k)
    d = np.sqrt(d2)
    d_ref, idx_ref = cKDTree(points).query(queries, k=k)
    d_ref, idx_ref = d_ref.reshape(len(queries), k), idx_ref.reshape(len(queries), k)
    assert np.array_equal(d, d_ref)  # every distance, nearest first
    d_b, idx_b = _brute(points, queries, k)
    assert np.array_equal(d, d_b) and np.array_equal(idx, idx_b)
    # Where no two of a query's distances tie (within its k and the next), the KD-tree's points and order.
    untied = np.array([len(np.unique(row)) == len(row) for row in _brute(points, queries, min(k + 1, len(points)))[0]])
    assert untied.any() or name in ("duplicates", "lattice", "one point")
    assert np.array_equal(idx[untied], idx_ref[untied])


@pytest.mark.parametrize("per_cell", [pytest.param(0.5, marks=pytest.mark.slow), 2.0, 8.0, 64.0])  # 0.5: ~30 s of CI
def test_the_grids_cell_size_changes_the_work_not_the_answer(per_cell):
    points = _clouds()["crowded"]
    d_b, idx_b = _brute(points, points[::7], 9)
    for search in (_k_nearest, _k_nearest_grouped):
        d2, idx = search(points, points[::7], 9, per_cell)
        assert np.array_equal(np.sqrt(d2), d_b) and np.array_equal(idx, idx_b)


def test_k_nearest_answers_as_the_kd_tree_on_both_sides_of_few_points():
    rng = np.random.default_rng(11)
    for n in (FEW_POINTS, FEW_POINTS + 1):
        points = rng.normal(size=(n, 3))
        d, idx = k_nearest(points, points[:300], 24)
        d_ref, idx_ref = cKDTree(points).query(points[:300], k=24)
        assert np.array_equal(d, d_ref) and np.array_equal(idx, idx_ref)


def test_k_outside_one_to_n_is_refused():
    with pytest.raises(ValueError):
        k_nearest(np.zeros((3, 3)), np.zeros((1, 3)), 4)
    with pytest.raises(ValueError):
        k_nearest(np.zeros((3, 3)), np.zeros((1, 3)), 0)
