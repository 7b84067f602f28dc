"""Elements edged where they can exist (lensmount.design.edges): faces that meet inside automatic
semi-diameters are clipped where a gap remains, what that vignettes is measured per field, and a
clip that would change the design's aperture is refused in one paragraph.

The lens: a stop 20 mm in front of an equi-convex N-BK7 singlet, R = ±20 mm, 4.28 mm thick, EPD 8
mm. Its faces meet where 2 (R - sqrt(R² - h²)) = 4.28 mm, h = 9.00 mm; the 13° field's beam reaches
9.13 mm on the front face, the axis's 4 mm.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from lensmount.cli import app
from lensmount.design.edges import MAX_CLIP_VIGNETTING, clip_crossing_elements
from lensmount.design.lens import load_lens_and_clips
from lensmount.errors import InputError
from lensmount.optics.apertures import vignetted_pupils
from lensmount.optics.io.lens_toml import read_lens_toml
from lensmount.optics.realrays import aim, trace

R, T = 20.0, 4.28


def _lens(tmp_path, field: float, epd: float = 8.0, given: str = "") -> str:
    path = tmp_path / "lens.toml"
    path.write_text(f'''name = "thick singlet behind its stop"
aperture = {{ entrance_pupil_diameter = {epd} }}
[wavelengths]
values_um = [0.5875618]
[field]
angles_deg = [0.0, {field}]
[[surface]]
radius = inf
thickness = 20.0
stop = true
[[surface]]
radius = {R}
thickness = {T}
material = "N-BK7"
{given}
[[surface]]
radius = {-R}
thickness = 15.0
''')
    return str(path)


def _height_with_gap(gap: float) -> float:
    """Where the two spheres are `gap` apart: each face's sag is (T - gap) / 2."""
    return math.sqrt(R * R - (R - 0.5 * (T - gap)) ** 2)


def test_faces_meeting_in_the_field_beam_are_clipped_where_the_gap_remains_and_the_loss_is_the_rays_beyond(tmp_path):
    raw, _ = read_lens_toml(_lens(tmp_path, 13.0))
    lens, clips = clip_crossing_elements(raw, 0.0, "lens.toml", gap=0.3)
    (clip,) = clips
    h = _height_with_gap(0.3)
    assert clip.surfaces == (1, 2) and clip.elements == (1,)
    assert clip.height == pytest.approx(h, abs=1e-9)
    assert lens.surfaces[1].clear_semi_diameter == lens.surfaces[2].clear_semi_diameter == pytest.approx(h)
    assert clip.meet == pytest.approx(_height_with_gap(0.0), abs=1e-9)
    # independent count: the unclipped lens's rays of the 13° field whose height on either face exceeds h
    g = np.arange(-1.0 + 0.01, 1.0, 0.02)
    x, y = np.meshgrid(g, g)
    disc = np.column_stack([x.ravel(), y.ravel()])
    disc = disc[np.einsum("ij,ij->i", disc, disc) <= 1.0]
    o, d = aim(raw, [13.0], vignetted_pupils(raw, [13.0], disc))
    heights = trace(raw, o, d).heights()
    beyond = (heights[1] > h) | (heights[2] > h)
    assert clip.lost[0] == 0.0
    assert 0.0 < clip.lost[1] < MAX_CLIP_VIGNETTING
    assert clip.lost[1] == pytest.approx(beyond.mean(), abs=2e-3)


def test_a_clip_that_takes_more_than_the_limit_of_a_field_is_refused_in_one_paragraph(tmp_path):
    path = _lens(tmp_path, 15.0)
    with pytest.raises(InputError) as err:
        load_lens_and_clips(path)
    text = err.value.paragraph()
    assert "cross each other" in text and "changes the design's aperture" in text and "\n" not in text
    result = CliRunner().invoke(app, ["inspect", path])
    assert result.exit_code == 2 and "Traceback" not in result.output


def test_a_clip_inside_the_on_axis_beam_is_refused(tmp_path):
    # EPD 18.4: the axis's beam reaches 9.2 mm, beyond where the faces meet (9.00 mm)
    with pytest.raises(InputError) as err:
        load_lens_and_clips(_lens(tmp_path, 2.0, epd=18.4))
    assert "at 0°" in err.value.paragraph() and "changes the design's aperture" in err.value.paragraph()


def test_faces_crossing_inside_a_semi_diameter_the_file_gives_stay_an_error(tmp_path):
    with pytest.raises(InputError) as err:
        load_lens_and_clips(_lens(tmp_path, 13.0, given="clear_semi_diameter = 9.2"))
    assert "cross each other" in err.value.paragraph() and "the file's" in err.value.paragraph()
