"""User errors: one paragraph naming file, field/line and what is valid; CLI exit code 2."""

import subprocess
import sys

from lensmount.errors import InputError


def test_paragraph_names_file_line_field_and_valid():
    err = InputError("radius 3 mm is smaller than the semi-diameter 5 mm", file="lens.toml",
                     field="surface[2].radius", line=14, valid="|radius| >= semi-diameter")
    text = err.paragraph()
    assert text.startswith("lens.toml, line 14, field 'surface[2].radius': radius 3 mm")
    assert text.endswith("Valid: |radius| >= semi-diameter.")
    assert "\n" not in text


def test_located_fills_in_a_missing_file_only():
    err = InputError("bad", field="x")
    assert err.located("a.toml").file == "a.toml"
    assert InputError("bad", file="b.toml").located("a.toml").file == "b.toml"


def test_a_line_stays_with_its_file_and_the_named_file_is_said_beside_the_field():
    """An error about the content of a file a field names (a STEP file) placed at that field's line of
    mount.toml: the line is mount.toml's, the STEP file is named separately."""
    err = InputError("not a readable STEP file", file="d/cad/ring.stp", field="parts.hood.step")
    text = err.located("d/mount.toml", line=57).paragraph()
    assert text.startswith("d/mount.toml, line 57, field 'parts.hood.step' (d/cad/ring.stp): not a readable")
    assert "d/cad/ring.stp, line 57" not in text
    assert err.located("d/mount.toml").file == "d/cad/ring.stp"  # no line: nothing to place


def test_cli_without_arguments_shows_help_not_a_traceback():
    proc = subprocess.run([sys.executable, "-c", "from lensmount.cli import main; main()"],
                          capture_output=True, text=True)
    assert "Traceback" not in proc.stderr
    assert "Usage" in proc.stdout + proc.stderr
