"""An afocal system is recognised (angular magnification, no focal length) and a lens that forms
no real image is refused with that reason, against hand-computed first-order optics."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from lensmount.cli import app
from lensmount.design.lens import load_lens
from lensmount.errors import InputError
from lensmount.optics.glass import refractive_index
from lensmount.optics.io.zemax import read_zmx
from lensmount.optics.paraxial import paraxial

D_LINE = 0.5875618
N = float(refractive_index("N-BK7", D_LINE))
C_OBJECTIVE, T_OBJECTIVE, R_EYEPIECE, T_EYEPIECE = 0.0193798, 5.0, 10.0, 3.0
F_OBJECTIVE = 1.0 / (C_OBJECTIVE * (N - 1.0))     # plano-convex: f = R / (n - 1), principal plane on the curve
F_EYEPIECE = R_EYEPIECE / (N - 1.0)
# the objective's rear focus meets the eyepiece's front focus: a Keplerian telescope
GAP = F_OBJECTIVE - T_OBJECTIVE / N + F_EYEPIECE - T_EYEPIECE / N

KEPLER = f"""UNIT MM
ENPD 20
FTYP 0 0 2 1 0 0 0
YFLN 0 1
WAVM 1 0.5875618 1
SURF 0
  DISZ INFINITY
SURF 1
  STOP
  CURV {C_OBJECTIVE!r}
  DISZ {T_OBJECTIVE!r}
  GLAS N-BK7
SURF 2
  DISZ {GAP!r}
SURF 3
  DISZ {T_EYEPIECE!r}
  GLAS N-BK7
SURF 4
  CURV {-1.0 / R_EYEPIECE!r}
  DISZ 20
SURF 5
"""

# Thorlabs's negative lenses put the image surface at the virtual focus, before the lens's last face
PLANO_CONCAVE = """UNIT MM
ENPD 10
WAVM 1 0.5875618 1
SURF 0
  DISZ INFINITY
SURF 1
  STOP
  CURV -0.04
  DISZ 3
  GLAS N-BK7
SURF 2
  DISZ -48.4
SURF 3
"""


@pytest.fixture()
def kepler(tmp_path):
    path = tmp_path / "kepler.zmx"
    path.write_text(KEPLER)
    return path


def test_a_keplerian_telescope_is_afocal_with_the_angular_magnification_of_its_focal_lengths(kepler):
    par = paraxial(read_zmx(kepler))
    assert par.afocal
    assert par.angular_magnification == pytest.approx(-F_OBJECTIVE / F_EYEPIECE, rel=1e-9)
    result = CliRunner().invoke(app, ["inspect", str(kepler), "--json"])
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert doc["afocal"] and doc["efl_mm"] is None and doc["f_number"] is None
    assert doc["angular_magnification"] == pytest.approx(-F_OBJECTIVE / F_EYEPIECE, rel=1e-9)
    shown = CliRunner().invoke(app, ["inspect", str(kepler)])
    assert shown.exit_code == 0 and "afocal" in shown.stdout and "effective focal length" not in shown.stdout


def test_a_focusing_lens_is_not_afocal_and_one_millimetre_of_defocus_makes_the_telescope_focal(tmp_path):
    path = tmp_path / "defocused.zmx"
    path.write_text(KEPLER.replace(f"DISZ {GAP!r}", f"DISZ {GAP + 1.0!r}"))
    par = paraxial(read_zmx(path))
    assert not par.afocal
    # two thin-lens groups d = f1 + f2 + 1 apart: power -1 / (f1 f2)
    assert par.efl == pytest.approx(-F_OBJECTIVE * F_EYEPIECE, rel=1e-9)


def test_init_and_simulate_refuse_an_afocal_system_in_one_paragraph(kepler, tmp_path):
    with pytest.raises(InputError) as err:
        load_lens(kepler)
    assert "afocal" in err.value.paragraph() and "\n" not in err.value.paragraph()
    result = CliRunner().invoke(app, ["init", str(tmp_path / "design"), "--lens", str(kepler)])
    assert result.exit_code == 2 and "afocal" in result.output and "Traceback" not in result.output
    assert not (tmp_path / "design" / "mount.toml").exists()


def test_a_negative_lens_is_refused_for_forming_no_real_image(tmp_path):
    path = tmp_path / "lc.zmx"
    path.write_text(PLANO_CONCAVE)
    with pytest.raises(InputError) as err:
        load_lens(path)
    text = err.value.paragraph()
    assert "forms no real image" in text and "total track" not in text
    f = -25.0 / (N - 1.0)                                  # plano-concave R -25: f = R / (n - 1)
    assert f"{f:.4g}" in text
    result = CliRunner().invoke(app, ["inspect", str(path)])
    assert result.exit_code == 2 and "forms no real image" in result.output
