"""Passes whose terms have a stated bound get the central limit's error bar; terms with no bound keep the tail rule.

A forward photon's flux is bounded by its emitted flux times its finishes' weights (`walk.gain_bound`); its terms
then come in weight classes (one bounce, two bounces), which are no power law. Checked against synthetic passes
of known distribution: two bounded weight classes with a Poisson-skewed heavy class (the error bar's coverage over
many runs is nominal, and the largest pass is not taken for an outlier), and Pareto terms with no bound (still no
error bar, or one widened by the tail allowance); against Bennett's inequality for the outlier test; and against
the closed-form bound of a Lambertian scene.
"""

import math

import numpy as np
import pytest

from lensmount.analysis.passes import (UNBOUNDED_TAIL, Accumulator, bounded_outlier_p, grubbs_p, tail_index)
from lensmount.integrators.estimate import Largest, PassEstimate

B = 8.9e-5  # one bounce's term (mm²; the Cooke triplet's at 35°, 10⁶ photons a pass); two bounces: B / 20


def _pass(terms: np.ndarray, bound: float) -> PassEstimate:
    largest = Largest()
    largest.add(terms)
    flux = float(terms.sum())
    return PassEstimate(np.array([[flux]]), np.array([[[flux]]]), ["p"], 1.0, len(terms), largest=largest.values,
                        term_bound=bound)


def _two_classes(rng, heavy: float, light: float) -> np.ndarray:
    """Poisson(heavy) terms of one bounce, Poisson(light) of two, each a little below its class's size (glass)."""
    sizes = np.r_[np.full(rng.poisson(heavy), B), np.full(rng.poisson(light), B / 20)]
    return sizes * rng.uniform(0.99, 1.0, len(sizes))


def _run(rng, passes: int, draw, bound: float) -> Accumulator:
    acc = Accumulator.empty((1, 1), ["p"], 1.0)
    for i in range(passes):
        acc.add(_pass(draw(rng), bound), i)
    return acc


def test_weight_classes_are_not_a_power_law():
    """The Cooke triplet's largest terms, 8.9e-5 and 4.5e-6 (a few one-bounce, many two-bounce photons): Hill's
    estimate across the two classes read 0.33 (no error bar); classes have no tail to fit. Continuous Pareto
    terms keep their index."""
    rng = np.random.default_rng(3)
    for heavy in (5, 64):  # 64 one-bounce terms of the run and the rest two-bounce: Hill read 64 / (64 ln 20) = 0.33
        classes = np.r_[np.full(heavy, B), np.full(200, B / 20)] * rng.uniform(0.99, 1.0, heavy + 200)
        assert tail_index(classes) == np.inf
    pareto = (1 - rng.random(5000)) ** (-1 / 1.5)
    assert 1.1 < tail_index(pareto) < 2.0


@pytest.mark.parametrize("alpha", [0.5, 1.5, 3.0])
def test_continuous_heavy_tails_are_not_taken_for_weight_classes(alpha):
    """Pareto terms below the light-tail index (where the index matters): in at most 1 % of 1000 runs of 65 terms
    do the largest look like classes; Hill's estimate keeps its value (median within 5 %)."""
    rng = np.random.default_rng(4)
    index = tail_index((1 - rng.random((1000, 65))) ** (-1 / alpha))
    assert np.mean(np.isinf(index)) <= 0.01 and abs(np.median(index) / alpha - 1) < 0.05


def test_bennett_outlier_p_is_a_valid_p_value_for_poisson_skewed_passes():
    """Passes of B × Poisson(λ) (the skew of a few heavy terms): the largest of 72 gets p < 0.01 in at most 1 %
    of runs (a valid p-value under the bound, Šidák over the passes), where Grubbs's normal test flags many more;
    a pass at 35 medians among passes of a dozen heavy terms each is flagged."""
    rng = np.random.default_rng(7)
    runs = rng.poisson(3.0, size=(2000, 72)) * B
    bennett = np.array([bounded_outlier_p(r, B) for r in runs])
    grubbs = np.array([grubbs_p(r) for r in runs])
    assert np.mean(bennett < 0.01) <= 0.01 and np.mean(grubbs < 0.01) > 3 * max(np.mean(bennett < 0.01), 0.01)
    runs = rng.poisson(12.0, size=(32,)) * B
    runs[5] = 35 * np.median(runs)
    assert bounded_outlier_p(runs, B) < 1e-6
    # one heavy term in the whole run (every other pass empty) is no outlier: the mean includes it
    assert bounded_outlier_p(np.r_[B, np.zeros(47)], B) > 0.5


def test_bounded_two_class_terms_get_an_error_bar_whose_coverage_is_nominal():
    """400 runs of 48 passes, each pass a sum of one-bounce (Poisson 2 a pass) and two-bounce (Poisson 170)
    terms, bound B stated: every run has an error bar, none is called heavy-tailed, and the truth lies within
    ±2 quoted standard errors in 92–98.5 % of the runs (95 % nominal)."""
    rng = np.random.default_rng(11)
    truth = (2.0 * B + 170.0 * B / 20) * 0.995
    held, heavy, refused = 0, 0, 0
    for _ in range(400):
        acc = _run(rng, 48, lambda r: _two_classes(r, 2.0, 170.0), B)
        se, t = acc.flux_std_error, acc.tail()
        refused += not math.isfinite(se)
        heavy += t.heavy
        held += abs(acc.flux - truth) <= 2 * se
        assert t.index is None and t.allowance == 0.0  # one-bounce terms, at the bound, were met
    assert refused == 0 and heavy <= 4
    assert 0.92 <= held / 400 <= 0.985, held / 400


@pytest.mark.parametrize("alpha", [0.8, 1.5])
def test_heavy_tailed_terms_with_no_bound_are_still_refused(alpha):
    """Pareto terms (α < 2: infinite variance), no bound stated: α ≤ 1 has no error bar at all, 1 < α < 2 one
    widened by the tail allowance beyond the passes' spread."""
    rng = np.random.default_rng(5)
    acc = _run(rng, 12, lambda r: (1 - r.random(2000)) ** (-1 / alpha), math.inf)
    t = acc.tail()
    if alpha <= UNBOUNDED_TAIL + 0.2:
        assert acc.flux_std_error == math.inf and acc.rel_error() == math.inf
    else:
        assert UNBOUNDED_TAIL < t.index < 2.5 and t.allowance > 0 and math.isfinite(acc.flux_std_error)


def test_a_bound_no_term_has_come_near_adds_one_term_at_it():
    """Only two-bounce terms met, the bound one bounce's (direct light counted, say): the allowance is B / n."""
    rng = np.random.default_rng(2)
    acc = _run(rng, 16, lambda r: _two_classes(r, 0.0, 170.0), B)
    assert acc.tail().allowance == pytest.approx(B / 16) and math.isfinite(acc.flux_std_error)


def test_a_lambertian_scene_states_its_albedo_as_the_bound_and_aiming_doubles_it():
    """`gain_bound`: ρ per unit emitted flux with every face Lambertian ρ (≤ 1), twice that where photons are aimed
    (one-sample MIS with half the directions from the BSDF), 1 when unscattered light is counted, none (inf)
    when a factor exceeds 1 (it compounds over the bounces)."""
    from types import SimpleNamespace

    from lensmount.integrators.settings import EstimatorSettings
    from lensmount.integrators.walk import gain_bound
    from lensmount.physics.bsdf import make_bsdf

    def scene(rho, direct=False, response=None):
        tags = [SimpleNamespace(finish="paint", part="p", role="wall")]
        return SimpleNamespace(optical=[], bsdf_of_tag=[make_bsdf("lambertian", reflectance=rho)],
                               effects=SimpleNamespace(direct=direct, ghosts=False, scatter=True, scatterers=None),
                               mesh=SimpleNamespace(tag_table=tags), finish_of_tag=["paint"],
                               detector=SimpleNamespace(spectral_weight=response))

    s = EstimatorSettings()
    assert gain_bound(scene(0.05), s) == pytest.approx(0.05)
    assert gain_bound(scene(0.05), s, aimed=True) == pytest.approx(0.10)
    assert gain_bound(scene(0.05, direct=True), s) == 1.0
    assert gain_bound(scene(0.05, response=(0.5, 0.8)), s) == pytest.approx(0.04)
    assert gain_bound(scene(0.6), s, aimed=True) == math.inf
    assert make_bsdf("gaussian", reflectance=0.1, half_width_deg=5.0).weight_bound < 0.21


def test_one_pass_at_35_medians_still_dominates_where_terms_have_no_bound():
    """The reference design's bidirectional run at 45°: one pass in 32 at 35× the median (a connection from a
    vane's edge to the housing). Its terms state no bound: Grubbs's test calls the run heavy-tailed, as before."""
    rng = np.random.default_rng(9)
    acc = Accumulator.empty((1, 1), ["p"], 1.0)
    for i in range(32):
        terms = rng.exponential(1.0, 500) * (35.0 if i == 17 else 1.0)
        acc.add(_pass(terms, math.inf), i)
    t = acc.tail()
    assert t.heavy and t.largest_pass == 17 and t.over_median > 30
