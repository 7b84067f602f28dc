"""`lensmount inspect`: tables, --json, and one-paragraph errors with exit code 2."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from typer.testing import CliRunner

from lensmount.cli import app

runner = CliRunner()

GOOD = """name = "singlet"
aperture = { entrance_pupil_diameter = 10.0 }

[[surface]]
radius = 50.0
thickness = 6.0
material = "N-BK7"
stop = true

[[surface]]
radius = -80.0
thickness = 90.0
"""

JSON_KEYS = ("efl_mm", "bfl_mm", "f_number", "epd_mm", "entrance_pupil_z_mm", "exit_pupil_z_mm",
             "exit_pupil_diameter_mm", "surfaces")
SURFACE_KEYS = ("radius_mm", "thickness_mm", "material", "n_primary", "clear_semi_diameter_mm")


def test_json_document_of_the_reference_lens(examples):
    result = runner.invoke(app, ["inspect", str(examples["double_gauss"]), "--json"])
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    for k in JSON_KEYS:
        assert k in doc
    assert doc["efl_mm"] == pytest.approx(360.013, rel=1e-4)
    assert doc["epd_mm"] == pytest.approx(51.430, abs=0.0015)
    assert doc["f_number"] == pytest.approx(7.0)
    assert len(doc["surfaces"]) == 11
    for s in doc["surfaces"]:
        for k in SURFACE_KEYS:
            assert k in s
        assert s["clear_semi_diameter_mm"] > 0
    assert doc["surfaces"][5]["radius_mm"] is None and doc["surfaces"][5]["is_stop"]


def test_twin_files_print_identical_json(examples):
    a = runner.invoke(app, ["inspect", str(examples["cooke_toml"]), "--json"])
    b = runner.invoke(app, ["inspect", str(examples["cooke_zmx"]), "--json"])
    assert a.exit_code == b.exit_code == 0
    da, db = json.loads(a.stdout), json.loads(b.stdout)
    # The .zmx's DIAMs are automatic (flag 0), written by lensmount's own writer (its GLAS lines carry the
    # 1.5/40 placeholders) from the beam aimed at the paraxial stop height, 3.8046 mm, and rounded to 0.01 mm.
    # Recomputed from real rays they are the twin lens.toml's automatic ones, now aimed at the stop's real-ray
    # size (the on-axis ray at EPD/2 crosses it at 3.8611 mm, as OpticStudio sizes an automatic stop): 1.5 %
    # wider beam, 0.05-0.08 mm more on every face than the file wrote. The stop keeps the file's 3.8.
    written = [9.29, 8.85, 4.34, 3.8, 6.93, 7.30]
    got = [s["clear_semi_diameter_mm"] for s in db["surfaces"]]
    assert got[3] == 3.8 and all(0.05 < g - w < 0.08 for k, (g, w) in enumerate(zip(got, written)) if k != 3)
    assert [s["clear_semi_diameter_mm"] for s in da["surfaces"]] == pytest.approx(got[:3] + [3.8611] + got[4:],
                                                                                     abs=1e-4)
    assert "import_notes" in db and "import_notes" not in da
    recomputed = [n for n in db["import_notes"] if "recomputed from real rays" in n["what"]]
    assert len(recomputed) == 5
    for n in recomputed:   # each says the value it got: the surface table's
        assert n["what"].endswith(f": {got[int(n['where'].split()[1]) - 1]:.4g} mm"), n
    db.pop("import_notes")
    for d in (da, db):
        d["surfaces"][3].pop("clear_semi_diameter_mm")
    assert da == db


def test_table_output_and_toml_conversion(examples, tmp_path):
    out = tmp_path / "converted.toml"
    result = runner.invoke(app, ["inspect", str(examples["cooke_zmx"]), "--save-toml", str(out)])
    assert result.exit_code == 0, result.output
    assert "effective focal length" in result.stdout and "STOP" in result.stdout
    again = runner.invoke(app, ["inspect", str(out), "--json"])
    direct = runner.invoke(app, ["inspect", str(examples["cooke_zmx"]), "--json"])
    converted, original = json.loads(again.stdout), json.loads(direct.stdout)
    assert original.pop("import_notes") and "import_notes" not in converted
    assert converted == original   # the file's semi-diameters are written into the toml


BAD_CASES = {
    "missing file": (None, "file not found"),
    "malformed toml": (("thickness = 6.0", "thickness = = 6.0"), "not valid TOML"),
    "unknown glass": (('"N-BK7"', '"N-BK7-NOPE"'), "unknown glass"),
    "negative glass thickness": (("thickness = 6.0", "thickness = -6.0"), "glass thickness"),
    "radius smaller than semi-diameter": (("radius = 50.0", "radius = 50.0\nclear_semi_diameter = 55.0"),
                                          "smaller than its clear semi-diameter"),
    "crossing surfaces": (("thickness = 6.0", "thickness = 0.1"), "cross each other"),
    "no stop": (("stop = true\n", ""), "stop"),
    "unknown key": (("stop = true", "stop = true\nwobble = 1"), "unknown key 'wobble'"),
}


@pytest.mark.parametrize("case", list(BAD_CASES))
def test_bad_input_is_one_paragraph_and_exit_code_2(tmp_path, case):
    edit, words = BAD_CASES[case]
    path = tmp_path / "lens.toml"
    if edit is not None:
        text = GOOD.replace(*edit)
        assert text != GOOD
        path.write_text(text, encoding="utf-8")
    result = runner.invoke(app, ["inspect", str(path)])
    assert result.exit_code == 2, (result.output, result.exception)
    err = result.stderr.strip()
    assert "Traceback" not in result.output
    assert err.count("\n") == 0                       # one paragraph
    assert err.startswith(f"error: {path}")           # names the file
    assert words in err
    assert "Valid:" in err                            # and what would be valid


def test_console_entry_point_prints_no_traceback(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-c", "import sys; from lensmount.cli import main; sys.argv[0] = 'lensmount'; main()",
         "inspect", str(tmp_path / "nope.toml")], capture_output=True, text=True)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.strip().count("\n") == 0 and "file not found" in proc.stderr


def test_a_recomputed_semi_diameter_reads_apart_from_the_files_or_is_said_to_be_it():
    """A semi-diameter the import recomputes from real rays is shown beside the file's value with
    the digits it takes to tell them apart; one equal to the file's to 1 µm says so instead of
    reading "64.39 mm ... -> 64.39 mm"."""
    from dataclasses import replace
    from pathlib import Path

    from lensmount.cli.inspect import inspect_document
    from lensmount.design.lens import import_notes, load_lens

    path = Path(__file__).parent / "corpus" / "US05831776-1.zmx"
    lens = load_lens(path)
    notes = [n for n in import_notes(path) if n.file_value_mm is not None]
    assert notes
    for row in inspect_document(lens, notes)["import_notes"]:
        given, shown = row["what"].split(" -> ")
        first = given.split(" mm")[0].split()[-1]
        assert f": {first} mm" not in shown or "the file's value to 1 µm" in shown, row
    note = notes[0]
    got = lens.surfaces[note.surface].clear_semi_diameter
    near = replace(note, file_value_mm=got + 0.002)  # apart in the 5th digit of 64.39 mm
    [row] = inspect_document(lens, [near])["import_notes"]
    assert f": {got:.5g} mm (the file's {got + 0.002:.5g} mm)" in row["what"], row
