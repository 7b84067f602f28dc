"""Lenses off one axis: frames from coordinate breaks, the trace through them, first-order data along the
folded axis; checked against hand traces written here (numpy, own rotation matrices) and Coddington's
focal lengths of a tilted sphere."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lensmount.cli import app
from lensmount.design.lens import load_lens
from lensmount.errors import InputError
from lensmount.optics.folded import folded_axis, placed
from lensmount.optics.io.zemax import convert, parse_zmx, read_zmx
from lensmount.optics.paraxial import paraxial

FOLDED = sorted((Path(__file__).parent / "corpus" / "folded").glob("*.zmx"))
CORPUS = sorted((Path(__file__).parent / "corpus").glob("*.zmx"))


def _zmx(*surfaces: str) -> str:
    body = "\n".join(f"SURF {k + 1}\n{s}" for k, s in enumerate(surfaces))
    return f"UNIT MM\nENPD 10\nWAVM 1 0.55 1\nSURF 0\n  DISZ INFINITY\nSURF 1\n  STOP\n  DISZ 10\n{body}"


def _lens(*surfaces: str):
    text = _zmx(*surfaces)
    lines, k = [], 0
    for line in text.splitlines():   # number the surfaces in order
        if line.startswith("SURF "):
            line, k = f"SURF {k}", k + 1
        lines.append(line)
    return convert(parse_zmx("\n".join(lines), "t.zmx"), "t.zmx")[0]


def _rx(deg):   # right-handed rotation about x, columns the turned axes
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _sphere_hit(o, d, centre, radius, vertex):
    """The crossing of the ray o + t d with the sphere on the vertex's side (of the two roots, the nearer the vertex)."""
    oc = o - centre
    b = d @ oc
    root = math.sqrt(b * b - (oc @ oc - radius * radius))
    hits = [o + t * d for t in (-b - root, -b + root)]
    return min(hits, key=lambda q: np.linalg.norm(q - vertex))


def _reflect(d, n):
    return d - 2 * (d @ n) * n


def test_a_45_degree_fold_mirror_decentred_matches_a_hand_trace_and_coddingtons_focal_lengths():
    r, dy, gap = -100.0, 3.0, -30.0
    fold = ["  TYPE COORDBRK\n  PARM 2 {dy}\n  PARM 3 45\n  DISZ 0", "  CURV {c}\n  GLAS MIRROR\n  DISZ 0",
            "  TYPE COORDBRK\n  PARM 3 45\n  DISZ {gap}", "  DISZ 0"]
    lens = _lens(*(s.format(dy=dy, c=1 / r, gap=gap) for s in fold))
    axis = folded_axis(lens)
    # by hand: the mirror's vertex 10 mm down the axis, decentred 3 mm in y, then turned -45° about x
    # (a positive Zemax tilt about x is left-handed); the chief ray runs down the axis (stop on it)
    m = _rx(-45.0)
    vertex = np.array([0.0, dy, 10.0])
    centre = vertex + m @ np.array([0.0, 0.0, r])
    hit = _sphere_hit(np.zeros(3), np.array([0.0, 0.0, 1.0]), centre, abs(r), vertex)
    out = _reflect(np.array([0.0, 0.0, 1.0]), (hit - centre) / abs(r))
    m2 = m @ _rx(-45.0)          # the second break turns the axis on by 45°: now along +y
    image_vertex = vertex + gap * m2[:, 2]
    normal = m2[:, 2]
    image = hit + ((image_vertex - hit) @ normal) / (out @ normal) * out
    assert np.allclose(axis.image_point, image, atol=1e-9)
    assert np.allclose(lens.frames[-1].origin, image_vertex, atol=1e-12)
    # undecentred: Coddington's tangential and sagittal focal lengths of a sphere met at 45°
    centred = _lens(*(s.format(dy=0.0, c=1 / r, gap=gap) for s in fold))
    a = folded_axis(centred)
    assert a.efl_y == pytest.approx(abs(r) / 2 * math.cos(math.radians(45.0)), rel=1e-7)
    assert a.efl_x == pytest.approx(abs(r) / 2 / math.cos(math.radians(45.0)), rel=1e-7)
    assert np.allclose(a.image_point, [0.0, gap, 10.0], atol=1e-9)   # along +y, gap negative after the mirror


def test_a_return_break_with_order_1_from_pickups_puts_the_axis_back_and_matches_a_hand_trace():
    dx, dy, tx, ty, r, back = 2.0, 1.0, 10.0, 5.0, -200.0, -80.0
    # the return break's values are written 0: they must come from the pickups (scale -1), its order is 1
    lens = _lens(f"  TYPE COORDBRK\n  PARM 1 {dx}\n  PARM 2 {dy}\n  PARM 3 {tx}\n  PARM 4 {ty}\n  PARM 6 0\n  DISZ 0",
                 f"  CURV {1 / r}\n  GLAS MIRROR\n  DISZ 0",
                 "  TYPE COORDBRK\n" + "".join(f"  PARM {k} 0\n  PPAR {k} 2 -1 0 0\n" for k in (1, 2, 3, 4))
                 + f"  PARM 6 1\n  DISZ {back}",
                 "  DISZ 0")
    # by hand: decentre, then tilt about x then y (both left-handed); the return tilts back, then decentres back
    m = _rx(-tx) @ _ry(-ty)
    vertex = np.array([dx, dy, 10.0])
    assert np.allclose(lens.frames[1].origin, vertex, atol=1e-12)
    assert np.allclose(np.array(lens.frames[1].rotation).reshape(3, 3), m, atol=1e-14)
    assert np.allclose(lens.frames[-1].rotation, np.eye(3).ravel(), atol=1e-14)   # back on the first axis
    assert np.allclose(lens.frames[-1].origin, [0.0, 0.0, 10.0 + back], atol=1e-12)
    centre = vertex + m @ np.array([0.0, 0.0, r])
    hit = _sphere_hit(np.zeros(3), np.array([0.0, 0.0, 1.0]), centre, abs(r), vertex)
    out = _reflect(np.array([0.0, 0.0, 1.0]), (hit - centre) / abs(r))
    image = hit + (10.0 + back - hit[2]) / out[2] * out
    assert np.allclose(folded_axis(lens).image_point, image, atol=1e-9)
    # the same return written with order 0 does not undo the break: the order is read
    wrong = _lens(f"  TYPE COORDBRK\n  PARM 1 {dx}\n  PARM 2 {dy}\n  PARM 3 {tx}\n  PARM 4 {ty}\n  DISZ 0",
                  f"  CURV {1 / r}\n  GLAS MIRROR\n  DISZ 0",
                  f"  TYPE COORDBRK\n  PARM 1 {-dx}\n  PARM 2 {-dy}\n  PARM 3 {-tx}\n  PARM 4 {-ty}\n  PARM 6 0\n"
                  f"  DISZ {back}", "  DISZ 0")
    assert not np.allclose(wrong.frames[-1].origin, [0.0, 0.0, 10.0 + back], atol=1e-6)


@pytest.mark.parametrize("path", CORPUS[:8], ids=[p.stem for p in CORPUS[:8]])
def test_a_coaxial_lens_has_no_frames_and_its_folded_axis_efl_is_its_paraxial_efl(path):
    p = read_zmx(path)
    assert p.frames == ()
    par = paraxial(p)
    if not par.afocal:
        assert folded_axis(placed(p)).efl_y == pytest.approx(par.efl, rel=1e-8)


@pytest.mark.parametrize("path", FOLDED, ids=[p.stem for p in FOLDED])
def test_a_folded_file_imports_inspect_shows_its_frames_and_the_mount_refuses_it_in_one_paragraph(path):
    p = read_zmx(path)
    assert p.frames and len(p.frames) == len(p.surfaces) + 1 and not all(f.is_axial for f in p.frames)
    hash(p)
    result = CliRunner().invoke(app, ["inspect", str(path)])
    assert result.exit_code == 0, result.output
    assert "frames" in result.output and "EFL y (folded axis)" in result.output
    with pytest.raises(InputError) as err:
        load_lens(path)
    text = err.value.paragraph()
    assert "\n" not in text and "one axis" in text and path.name in text
