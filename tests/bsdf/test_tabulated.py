"""Tabulated (measured) BSDFs: the readers' geometry, the Harvey reduction, the ABg fit, energy at load time."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lensmount.design.brdf_data import read_brdf
from lensmount.errors import InputError
from lensmount.physics.bsdf import make_bsdf
from lensmount.physics.bsdf.tabulated import fit_abg, measured_profile

A, B, G = 2e-3, 1e-3, 2.0  # black-paint-like ABg: a 1.8° shoulder, most of the TIS in the wings


def abg(rho):
    return A / (B + rho ** G)


def _zemax_file(path, f_of_rho, aoi=(0, 20, 40, 60), azimuth=tuple(range(0, 360, 30)),
                radial=(0, 0.5, 1, 2, 5, 10, 20, 40, 60, 80)):
    """A .bsdf file whose values come from f(ρ), with ρ computed here from spherical trigonometry alone."""
    lines = ["# synthetic", "Source  Measured", "Symmetry  PlaneSymmetrical", "SpectralContent  Monochrome",
             "ScatterType  BRDF", "SampleRotation  1", "0", f"AngleOfIncidence  {len(aoi)}", " ".join(map(str, aoi)),
             f"ScatterAzimuth  {len(azimuth)}", " ".join(map(str, azimuth)), f"ScatterRadial  {len(radial)}",
             " ".join(map(str, radial)), "", "Monochrome", "DataBegin"]
    for s in aoi:
        lines.append("TIS 0.1")
        for az in azimuth:
            row = []
            for r in radial:
                # Scatter direction: the specular one rotated by r toward azimuth az (0 = toward the normal).
                sr, rr, ar = map(math.radians, (s, r, az))
                cos_t = math.cos(sr) * math.cos(rr) + math.sin(sr) * math.sin(rr) * math.cos(ar)  # spherical cosine law
                x = math.sin(sr) * math.cos(rr) - math.cos(sr) * math.sin(rr) * math.cos(ar)
                y = math.sin(rr) * math.sin(ar)
                rho = math.hypot(x - math.sin(sr), y)
                row.append(f"{f_of_rho(rho):.6e}" if cos_t > 0 else "0")
            lines.append(" ".join(row))
    lines.append("DataEnd")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_zemax_reader_geometry_gives_back_the_lobe(tmp_path):
    rho, f = read_brdf(_zemax_file(tmp_path / "paint.bsdf", abg))
    np.testing.assert_allclose(f, abg(rho), rtol=1e-5)  # the reader's ρ is the one f was computed at
    assert rho.min() == 0.0 or rho.min() < 1e-6


def test_csv_reader_in_plane_points(tmp_path):
    rows = ["incidence_deg,scatter_deg,brdf"]
    expected = []
    for inc in (0.0, 30.0, 60.0):
        for sc in (-80.0, -30.0, 0.0, 10.0, 29.0, 45.0, 89.0):
            rho = abs(math.sin(math.radians(sc)) - math.sin(math.radians(inc)))
            rows.append(f"{inc},{sc},{abg(rho):.8e}")
            expected.append(rho)
    (tmp_path / "m.csv").write_text("\n".join(rows) + "\n")
    rho, f = read_brdf(tmp_path / "m.csv")
    np.testing.assert_allclose(np.sort(rho), np.sort(expected), atol=1e-12)


@pytest.mark.parametrize("bad,field", [("incidence,scatter,brdf\n1,2,3\n", None), ("incidence_deg,scatter_deg,brdf\n1,x,3\n", None)])
def test_csv_errors_name_the_file(tmp_path, bad, field):
    (tmp_path / "bad.csv").write_text(bad)
    with pytest.raises(InputError) as e:
        read_brdf(tmp_path / "bad.csv")
    assert "bad.csv" in e.value.paragraph()


def test_table_from_a_measurement_has_the_analytic_models_tis(tmp_path):
    rho, f = read_brdf(_zemax_file(tmp_path / "paint.bsdf", abg))
    table = make_bsdf("tabulated", **dict(zip(("rho", "brdf"), measured_profile(rho, f, bins_per_decade=20))))
    reference = make_bsdf("abg", A=A, B=B, g=G)
    assert table.tis == pytest.approx(reference.tis, rel=0.03)


def test_fit_recovers_abg_from_noiseless_and_noisy_points(tmp_path):
    rho, f = read_brdf(_zemax_file(tmp_path / "paint.bsdf", abg))
    a, b, g, rms = fit_abg(rho, f)
    assert (a, b, g) == (pytest.approx(A, rel=1e-3), pytest.approx(B, rel=1e-3), pytest.approx(G, rel=1e-3))
    noisy = f * np.exp(np.random.default_rng(3).normal(0.0, 0.1, len(f)))
    a, b, g, rms = fit_abg(rho, noisy)
    assert g == pytest.approx(G, rel=0.05) and a / b == pytest.approx(A / B, rel=0.2) and rms > 0.02


def test_a_table_that_reflects_more_than_it_receives_is_refused():
    with pytest.raises(InputError) as e:
        make_bsdf("tabulated", rho=[0.01, 0.5, 1.0], brdf=[1.0, 0.5, 0.4])
    assert e.value.field == "brdf" and "TIS" in e.value.paragraph()


def test_a_rising_table_is_refused():
    with pytest.raises(InputError):
        make_bsdf("tabulated", rho=[0.01, 0.1], brdf=[0.01, 0.02])


def test_design_finish_from_a_measurement_relative_to_the_design_folder(tmp_path):
    from lensmount.design.finishes import load_finishes

    (tmp_path / "data").mkdir()
    _zemax_file(tmp_path / "data" / "paint.bsdf", abg)
    (tmp_path / "finishes.toml").write_text('[finishes]\npaint = { model = "tabulated", file = "data/paint.bsdf" }\n'
                                            '[assign]\n"*" = "paint"\n')
    table = load_finishes(tmp_path).finishes["paint"]  # the table read in, not the file name
    assert make_bsdf(**table).tis == pytest.approx(make_bsdf("abg", A=A, B=B, g=G).tis, rel=0.05)
    (tmp_path / "finishes.toml").write_text('[finishes]\npaint = { model = "tabulated", file = "paint.bsdf" }\n')
    with pytest.raises(InputError) as e:
        load_finishes(tmp_path)
    assert e.value.field == "finishes.paint.file" and e.value.file == str(tmp_path / "finishes.toml")
    assert e.value.line == 2


def test_scene_file_finish_from_a_measurement(tmp_path):
    from lensmount.design.scene import scene_from_dict

    _zemax_file(tmp_path / "paint.bsdf", abg)
    doc = {"source": {"type": "sun", "off_axis_deg": 7.0}, "detector": {"width_mm": 10.0, "height_mm": 10.0,
                                                                      "pixels": [10, 10]},
           "finishes": {"paint": {"model": "tabulated", "file": "paint.bsdf"}}, "assign": {"*": "paint"}}
    spec = scene_from_dict(doc, base_dir=str(tmp_path))
    table = spec.finishes["paint"]
    bsdf = make_bsdf(**table)
    assert bsdf.tis == pytest.approx(make_bsdf("abg", A=A, B=B, g=G).tis, rel=0.05)
    doc["finishes"]["paint"]["file"] = "missing.bsdf"
    with pytest.raises(InputError) as e:
        scene_from_dict(doc, base_dir=str(tmp_path))
    assert e.value.field == "finishes.paint.file" and "missing.bsdf" in e.value.paragraph()
