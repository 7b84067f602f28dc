"""Shared lenses for the optics tests (loaded once per session; loading is pure)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from lensmount.optics.prescription import Aperture, Prescription, Surface

ROOT = Path(__file__).resolve().parents[2]
DOUBLE_GAUSS = ROOT / "examples" / "double-gauss-360" / "lens.toml"
COOKE_TOML = ROOT / "examples" / "cooke-triplet" / "lens.toml"
COOKE_ZMX = ROOT / "examples" / "cooke-triplet" / "cooke-triplet.zmx"  # not lens.zmx: one lens file per design


@pytest.fixture(scope="session")
def double_gauss():
    from lensmount.design.lens import load_lens

    return load_lens(DOUBLE_GAUSS)


@pytest.fixture(scope="session")
def double_gauss_raw():
    from lensmount.design.lens import load_lens

    return load_lens(DOUBLE_GAUSS, auto_clear_apertures=False)


def singlet(r1=50.0, r2=-80.0, t=8.0, glass="N-BK7", stop_first=True, gap=0.0, back=80.0, epd=10.0):
    """A singlet; optionally a plane stop `gap` mm in front of it."""
    surfaces = []
    if stop_first:
        surfaces.append(Surface(radius=math.inf, thickness=gap, is_stop=True))
    surfaces += [Surface(radius=r1, thickness=t, material=glass, is_stop=not stop_first),
                 Surface(radius=r2, thickness=back)]
    return Prescription(tuple(surfaces), Aperture("epd", epd))


def plate(t=10.0, glass="N-BK7", epd=10.0):
    """A plane-parallel plate in air (stop on its front face)."""
    return Prescription((Surface(thickness=t, material=glass, is_stop=True), Surface(thickness=50.0)),
                        Aperture("epd", epd))


@pytest.fixture(scope="session")
def make_singlet():
    return singlet


@pytest.fixture(scope="session")
def make_plate():
    return plate


@pytest.fixture(scope="session")
def examples():
    """Paths of the example lenses."""
    return {"double_gauss": DOUBLE_GAUSS, "cooke_toml": COOKE_TOML, "cooke_zmx": COOKE_ZMX}
