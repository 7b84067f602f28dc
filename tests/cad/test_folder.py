"""Design folder: what it holds, and a content hash that follows every CAD input."""

import pytest

from lensmount.design.folder import load_design
from lensmount.errors import InputError


def test_hash_follows_lens_mount_and_templates(tmp_path, design_copier):
    d = design_copier("cooke-triplet", tmp_path / "d")
    (d / "scenes").mkdir()
    (d / "scenes" / "sun-7deg.toml").write_text("description = 'x'\n")
    first = load_design(d)
    assert first.scenes == {"sun-7deg": d / "scenes" / "sun-7deg.toml"}
    assert first.lens_path.name == "lens.toml" and len(first.prescription.surfaces) == 6
    assert load_design(d).input_hash == first.input_hash  # deterministic
    (d / "scenes" / "sun-7deg.toml").write_text("description = 'y'\n")
    assert load_design(d).input_hash == first.input_hash  # scenes are not CAD inputs

    (d / "hood.py").write_text("def make_part(name, params):\n    return None\n")
    text = (d / "mount.toml").read_text() + '\n[templates]\nhood = "hood.py"\n'
    (d / "mount.toml").write_text(text)
    with_template = load_design(d)
    assert with_template.input_hash != first.input_hash
    assert with_template.template_paths == {"hood": d / "hood.py"}
    (d / "hood.py").write_text("def make_part(name, params):\n    return 1\n")
    assert load_design(d).input_hash != with_template.input_hash


def test_missing_pieces_are_input_errors(tmp_path, design_copier):
    with pytest.raises(InputError):
        load_design(tmp_path / "nowhere")
    d = design_copier("cooke-triplet", tmp_path / "d")
    (d / "mount.toml").unlink()
    with pytest.raises(InputError) as exc:
        load_design(d)
    assert "mount.toml" in exc.value.paragraph()
    d2 = design_copier("cooke-triplet", tmp_path / "d2")
    (d2 / "mount.toml").write_text('[templates]\nhood = "missing.py"\n')
    with pytest.raises(InputError) as exc:
        load_design(d2)
    assert exc.value.field == "templates.hood"


@pytest.mark.slow  # US 5,831,776's three automatic-semi-diameter traces: ~5 s
def test_a_lens_edged_inside_its_beam_carries_the_warning_into_the_design(tmp_path, design_copier):
    """What the import clipped (design.edges) rides with the design, so that regenerate's manifest and
    simulate's summary.json say it; a lens with nothing clipped carries nothing."""
    from pathlib import Path

    d = design_copier("cooke-triplet", tmp_path / "d")
    assert load_design(d).lens_warnings == ()
    (d / "lens.toml").unlink()
    corpus = Path(__file__).resolve().parents[1] / "optics" / "corpus" / "US05831776-1.zmx"
    (d / "lens.zmx").write_bytes(corpus.read_bytes())
    warnings = load_design(d).lens_warnings
    assert [w.split(" are edged")[0] for w in warnings] == ["surfaces 15 and 16", "surfaces 24 and 25",
                                                            "surfaces 28 and 29"]
    assert "0.00 % at 0 mm" in warnings[-1] and "all 3 clips together" in warnings[-1]
