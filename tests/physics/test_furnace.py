"""White furnace: a closed Lambertian enclosure of albedo ρ, lit from inside by photons of total
flux Φ0, receives Φ0 (1 + ρ + ρ² + ...) = Φ0 / (1 − ρ) on its walls.

This checks, together: no photon leaks through the mesh seams (curved icosphere and a box
with corners), the scatter weight f cos/pdf, and that Russian roulette is unbiased.
"""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.trace.geometry import mech_scene  # noqa: E402
from lensmount.integrators.estimate import EnergyLedger, Film, ledger_residual  # noqa: E402
from lensmount.integrators.settings import EstimatorSettings  # noqa: E402
from lensmount.integrators.walk import photon_walk  # noqa: E402
from lensmount.scene import primitives  # noqa: E402
from lensmount.physics.rays import RayBatch  # noqa: E402
from lensmount.physics.sampler import stream  # noqa: E402
from lensmount.trace.tracer import FACE, GONE, Tracer  # noqa: E402


def _furnace(mesh, rho, n, seed, start):
    scene = mech_scene(mesh, finishes={"wall": {"model": "lambertian", "reflectance": rho}}, assign={"*": "wall"})
    tracer = Tracer(scene)
    rng = stream(seed, "furnace", 0)
    d = rng.normal(size=(n, 3))
    rays = RayBatch.make(np.broadcast_to(start, (n, 3)), d)
    per_photon = np.zeros(n)
    escaped = 0
    ledger = EnergyLedger()
    for step in photon_walk(scene, tracer, rays, seed, "furnace", EstimatorSettings(max_bounces=200), Film(scene),
                            ledger):
        ev = step.events
        face = ev.kind == FACE
        per_photon += np.bincount(ev.id[face], weights=ev.weight[face], minlength=n)
        escaped += int(((ev.kind == GONE) & ~ev.lost).sum())
    entries = ledger.as_dict()
    # Every photon's flux ends absorbed in the walls (roulette's balance is zero-mean noise).
    assert abs(ledger_residual(entries)) < 1e-12, entries
    assert all(k in ("source", "roulette_balance") or k.startswith("absorbed/") for k, v in entries.items() if v), entries
    return per_photon, escaped, sum(v for k, v in entries.items() if k.startswith("lost/"))


@pytest.mark.parametrize("rho", [0.3, 0.8])
@pytest.mark.parametrize("shape", ["icosphere", "box"])
def test_white_furnace_energy_balance(shape, rho):
    if shape == "icosphere":
        mesh, start = primitives.sphere((1.0, 2.0, 30.0), 20.0, subdivisions=2), np.array([4.0, 1.0, 33.0])
    else:
        mesh, start = primitives.box((-5, -8, 0), (15, 8, 30)), np.array([0.0, 0.0, 10.0])
    n = 20000
    tally, escaped, lost = _furnace(mesh, rho, n, seed=7, start=start)
    assert escaped == 0 and lost == 0.0
    mean, err = tally.mean(), tally.std(ddof=1) / np.sqrt(n)
    expected = 1.0 / (1.0 - rho)
    assert abs(mean - expected) < 4.0 * err, (mean, err, expected)
    assert err < 0.02 * expected  # the check has teeth: a 10 % bias would be ~5σ or more


def test_furnace_black_walls_absorb_everything():
    mesh = primitives.box((-5, -5, 0), (5, 5, 10))
    tally, escaped, _ = _furnace(mesh, 0.0, 2000, seed=7, start=np.array([0.0, 0.0, 5.0]))
    np.testing.assert_allclose(tally, 1.0)
    assert escaped == 0
