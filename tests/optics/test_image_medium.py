"""An image formed in a medium (an immersion objective's water or oil, n' != 1): first-order optics,
real rays and the radiance factor against the textbook results, and the two public objectives that
were refused for it (tests/optics/corpus, SOURCES.md).

The reference numbers are derived here from Snell's law and the paraxial transfer, never from lensmount:
- a plane-parallel plate of index n and thickness t before a focus moves it by t (1 - 1/n);
- light converging to a focus a distance s behind a plane face focuses n s behind it in a medium n
  (the reduced distance s = s'/n is what the converging cone keeps);
- n sin U is invariant across a plane face, so the image-space NA of an immersed image is the NA the
  same cone has in air, while its angle shrinks; the rear focal length in the medium is n' times the
  focal length referred to air.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lensmount.cli import app
from lensmount.design.lens import load_lens
from lensmount.errors import InputError
from lensmount.optics.io.zemax import read_zmx_with_notes
from lensmount.optics.paraxial import paraxial
from lensmount.optics.prescription import Aperture, Prescription, Surface
from lensmount.optics.realrays import marginal_ray
from lensmount.scene.build import detector_medium_index

CORPUS = Path(__file__).parent / "corpus"
WATER, PLATE = "1.333/0", "1.5/0"   # constant-index model glasses: n is exact at every wavelength
N_W, N_P = 1.333, 1.5
EPD = 10.0


def _singlet(*rear: Surface, back: float) -> Prescription:
    """A 50 mm-ish N-BK7 biconvex singlet, stop on its front face, then `rear` surfaces; `back` is the
    air gap after the singlet."""
    surfaces = (Surface(60.0, 5.0, "N-BK7", is_stop=True), Surface(-60.0, back)) + rear
    return Prescription(surfaces, Aperture("epd", EPD))


def _air_focus() -> tuple[float, float]:
    """(z of the paraxial focus in air, efl) of the bare singlet."""
    par = paraxial(_singlet(back=50.0))
    return par.image_z, par.efl


def test_a_plate_before_the_image_moves_the_focus_by_t_times_one_minus_one_over_n():
    z0, _ = _air_focus()
    t, gap = 4.0, 10.0
    lens = _singlet(Surface(math.inf, t, PLATE), Surface(math.inf, 30.0), back=gap)
    assert paraxial(lens).image_z - z0 == pytest.approx(t * (1.0 - 1.0 / N_P), rel=1e-12)


def test_an_image_in_water_lies_n_times_further_behind_the_plane_face_with_the_same_na():
    z0, efl = _air_focus()
    gap = 30.0                             # the plane face 30 mm behind the singlet, in front of the air focus
    face_z = 5.0 + gap
    s = z0 - face_z                        # where the cone would focus behind the face in air
    lens = _singlet(Surface(math.inf, 25.0, WATER), back=gap)
    par = paraxial(lens)
    assert lens.image_medium == WATER and lens.immersion_face == 2 and lens.lens_groups() == [(0, 1)]
    assert par.image_z - face_z == pytest.approx(N_W * s, rel=1e-12)
    assert par.efl == pytest.approx(efl, rel=1e-12)                       # power is the medium's business
    assert par.image_space_focal_length == pytest.approx(N_W * efl, rel=1e-12)
    assert par.image_na == pytest.approx(EPD / (2.0 * efl), rel=1e-12)   # n' u' = y Φ: the same cone
    assert par.f_number == pytest.approx(efl / EPD, rel=1e-12)


def test_a_real_marginal_ray_keeps_n_sin_u_across_the_face_into_water():
    """The real ray's NA in the medium (n' sin U') equals the air-side sin U of the same ray at the
    plane face: the sequential trace refracts into the water's index at its last segment."""
    gap = 30.0
    air = marginal_ray(_singlet(back=50.0))
    wet = marginal_ray(_singlet(Surface(math.inf, 25.0, WATER), back=gap))
    sin_air = math.hypot(*air.directions[1, 0, :2])
    sin_wet = math.hypot(*wet.directions[2, 0, :2])
    assert sin_wet < sin_air                                       # the cone narrows in the water ...
    assert N_W * sin_wet == pytest.approx(sin_air, rel=1e-12)      # ... and keeps its NA


def test_the_detector_behind_the_immersion_face_is_in_the_medium_and_in_front_of_it_in_air():
    lens = _singlet(Surface(math.inf, 25.0, WATER), back=30.0)
    wl = np.array([0.5, 0.6])
    assert detector_medium_index(lens, lens.image_z, wl) == (N_W, N_W)
    assert detector_medium_index(lens, 30.0, wl) == ()          # moved in front of the face: in air
    assert detector_medium_index(_singlet(back=50.0), 60.0, wl) == ()


def test_a_cover_glass_on_water_is_a_plate_element_and_the_water_is_none():
    """The OptoSigma water-dipping objective: ... S-LAH64 asphere, 11.93 mm of air, a 0.17 mm B270 cover
    glass, 0.2 mm of water to the specimen plane. The stop plane the file puts 6e-7 mm in front of the
    first lens's plane face is that face's."""
    lens, notes = read_zmx_with_notes(CORPUS / "cots-0002-12-1-optosigma-water-immersion.zmx")
    n = len(lens.surfaces)
    assert lens.image_medium == "1.33304403094/55.794321507"   # the file's n_d to its last digit
    assert lens.immersion_face == n - 1
    assert lens.lens_groups()[-1] == (n - 2, n - 1)            # the 0.17 mm B270 plate
    assert lens.surfaces[n - 2].thickness == pytest.approx(0.17) and lens.image_z - lens.vertex_z[-1] == pytest.approx(0.2)
    assert lens.stop_index == 0 and lens.surfaces[0].material == "N-BK7"
    assert any("the stop is that face" in note.what for note in notes)


def test_an_image_solved_before_its_last_face_inside_the_glass_is_refused_as_virtual():
    """optiland's 20x objective: the image solve put the image plane 0.196 mm before the N-K5 cover glass's
    face, inside the glass: the paraxial focus of the beam lies before that face (the beam crosses the
    axis in the air in front of it and diverges in the glass), so the image in the glass is virtual."""
    path = CORPUS / "refused" / "forms-microscope-objective-20x-virtual-image.zmx"
    lens, _ = read_zmx_with_notes(path)
    par = paraxial(lens)
    assert lens.surfaces[-1].thickness == pytest.approx(-0.196446, abs=1e-6)
    assert par.bfl < 0.0 and lens.surfaces[-1].thickness < 0.0    # the focus lies before the face, in the glass
    with pytest.raises(InputError) as err:
        load_lens(path)
    assert "virtual" in err.value.paragraph() and "surface 10" in err.value.paragraph()
    result = CliRunner().invoke(app, ["inspect", str(path)])
    assert result.exit_code == 2 and "Traceback" not in result.output
