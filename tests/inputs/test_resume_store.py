"""`simulate --resume` into the same --out records a new store row and leaves the earlier row's
files as they were (row 2's summary and images must not hold run 3's data); a paint change
in finishes.toml is a new input hash, a longer run of the same design is not. Tiny runs on the
Cooke triplet (12 × 8 pixels, 2000 photons per pass)."""

import json

from lensmount.run.results import read_exr
from lensmount.run.store import Store
from tests.inputs.conftest import edit, simulate


def test_resume_into_the_same_out_leaves_the_earlier_row_unchanged(cooke, monkeypatch):
    design, out = cooke
    store_path = design / ".lensmount" / "runs.sqlite"
    monkeypatch.delenv("LENSMOUNT_STORE", raising=False)
    first = simulate(design, out, "--passes", "1")
    assert first.exit_code == 0, first.output
    with Store(store_path) as store:
        (row1,) = store.runs()
    before = (open(row1.summary_path).read(), read_exr(row1.image_path)["Y"].copy())

    resumed = simulate(design, out, "--passes", "3", "--resume")
    assert resumed.exit_code == 0, resumed.output
    assert json.loads((out / "summary.json").read_text())["passes"] == 3  # the live folder holds the longer run
    with Store(store_path) as store:
        row1_again, row2 = store.runs()
    assert row1_again.summary_path == row1.summary_path and row2.summary_path != row1.summary_path
    assert open(row1.summary_path).read() == before[0]  # the earlier row still reads its own run
    assert (read_exr(row1.image_path)["Y"] == before[1]).all()
    assert json.loads(open(row1.summary_path).read())["passes"] == 1
    assert json.loads(open(row2.summary_path).read())["passes"] == 3
    assert row1.input_hash == row2.input_hash  # a longer run of the same design and test condition

    edit(design / "finishes.toml", "reflectance = 0.10", "reflectance = 0.20")  # a paint change: another design
    again = simulate(design, out, "--passes", "1", "--resume")
    assert again.exit_code == 2 and "input_hash" in again.output, again.output  # not resumed onto other inputs
