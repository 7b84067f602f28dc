"""Every reader of user input, fed malformed inputs at scale (Hypothesis, `tests.inputs.fuzz_inputs`).

Each generated file must end in a successful load with no NaN anywhere in what was loaded, or in an
`InputError` whose paragraph names the file: no other exception. Through the CLI (`inspect`, which
only reads), exit 0 or 2, an error as one paragraph, no traceback, nothing written.

Seeds are recorded: Hypothesis runs derandomized (the same inputs on every run, no example
database). The fast suite tries FAST inputs per reader; the slow one SLOW per reader (2 000, so the full
suite keeps its time); `make fuzz` runs the slow tests alone with LENSMOUNT_FUZZ_INPUTS=10000. Each
test prints how many inputs it tried, loaded and refused. A bug the fuzzing found stays as an
`@example` of the input that showed it.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from pydantic import BaseModel
from typer.testing import CliRunner

from lensmount.cli import app
from lensmount.design.finishes import load_finishes
from lensmount.design.lens import load_lens
from lensmount.design.mount import load_mount
from lensmount.design.scene import load_scene
from lensmount.errors import InputError
from lensmount.optics.io.agf import read_agf
from lensmount.validation import parse_toml
from tests.inputs.fuzz_inputs import AGF_KEYWORDS, ZMX_KEYWORDS, keyword_lines, mutated, toml_tree

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "src" / "lensmount" / "examples"
CORPUS = ROOT / "tests" / "optics" / "corpus"
FAST, SLOW = 300, int(os.environ.get("LENSMOUNT_FUZZ_INPUTS", "2000"))
# Corpus files that load in tens of ms (a patent's finite-conjugate lens takes seconds: too slow for 10⁴).
ZMX_SEEDS = ["thorlabs-AC254-050-B.zmx", "thorlabs-AC127-025-A.zmx", "thorlabs-AL2520-A.zmx", "edmund-49270.zmx",
             "thorlabs-ACL3026U-utf16.zmx", "optiland-lens1.zmx", "thorlabs-AL1210-A-latin1.zmx"]
# The optics tests' one-glass catalogue, with a second glass and a formula-3 one behind it.
AGF = (CORPUS.parent / "data" / "user-catalogue.agf").read_bytes() + b"""NM MYFLINT 1 0 1.62 36.4 0 0 0
CD 2.56 -0.0103 0.0217 0.0008 -3.4e-05 3.1e-06
LD 0.35 2.3
NM HERZ 3 0 1.5 60 0 0 0
CD 1.5 0.004 0.0001 -0.002 1e-05 -1e-07
"""


def _seeds(paths) -> list[bytes]:
    return [Path(p).read_bytes() for p in paths]


LENS_TOML = _seeds(sorted(EXAMPLES.glob("*/lens.toml")))
MOUNT_TOML = _seeds(sorted(EXAMPLES.glob("*/mount.toml")))
FINISHES_TOML = _seeds(sorted(EXAMPLES.glob("*/finishes.toml")))
SCENE_TOML = _seeds(sorted(EXAMPLES.glob("*/scenes/*.toml")))
ZMX = _seeds(CORPUS / name for name in ZMX_SEEDS)
STEP = _seeds([ROOT / "tests" / "cad" / "data" / "uc2" / "20_Cube_Insert_Thorlabs.stp"])


def _tomls(seeds):
    return [parse_toml(s.decode(), "seed") for s in seeds]


def _no_nan(value, where="") -> None:
    """Fails on a NaN anywhere in a loaded object (dataclasses, pydantic models, containers, arrays)."""
    if isinstance(value, float):
        assert not math.isnan(value), f"NaN at {where}"
    elif isinstance(value, np.ndarray):
        assert not (value.dtype.kind in "fc" and np.isnan(value).any()), f"NaN at {where}"
    elif isinstance(value, BaseModel):
        for k in type(value).model_fields:
            _no_nan(getattr(value, k), f"{where}.{k}")
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        for f in dataclasses.fields(value):
            _no_nan(getattr(value, f.name), f"{where}.{f.name}")
    elif isinstance(value, dict):
        for k, v in value.items():
            _no_nan(v, f"{where}[{k!r}]")
    elif isinstance(value, (list, tuple)):
        for k, v in enumerate(value):
            _no_nan(v, f"{where}[{k}]")


def _outcome(path: Path, data: bytes, load) -> str:
    path.write_bytes(data)
    try:
        loaded = load(path)
    except InputError as exc:
        assert str(path) in exc.paragraph(), exc.paragraph()
        return "refused"
    _no_nan(loaded, path.name)
    return "loaded"


def _fuzz(name, strategy, load, path: Path, n: int, examples=()) -> Counter:
    """Run `load` on n generated inputs written to `path` (and the regression examples); the counts."""
    counts: Counter = Counter()

    @settings(max_examples=n, derandomize=True, database=None, deadline=None,
              suppress_health_check=list(HealthCheck))
    @given(strategy)
    def run(data):
        counts[_outcome(path, data, load)] += 1

    for data in examples:
        run = example(data)(run)
    run()
    tried = sum(counts.values())
    print(f"\n{name}: {tried} inputs ({counts['loaded']} loaded, {counts['refused']} refused with InputError)")
    assert tried >= n
    return counts


SIZES = [FAST, pytest.param(SLOW, marks=pytest.mark.slow)]


@pytest.fixture(scope="module")
def example_finishes():
    return load_finishes(EXAMPLES / "double-gauss-360")


@pytest.mark.parametrize("n", SIZES)
def test_zmx_reader(n, tmp_path):
    strategy = st.one_of(mutated(ZMX), keyword_lines(ZMX, ZMX_KEYWORDS))
    _fuzz(".zmx", strategy, load_lens, tmp_path / "lens.zmx", n, ZMX_EXAMPLES)


@pytest.mark.parametrize("n", SIZES)
def test_agf_reader(n, tmp_path):
    strategy = st.one_of(mutated([AGF]), keyword_lines([AGF], AGF_KEYWORDS))
    _fuzz(".agf", strategy, read_agf, tmp_path / "MYVENDOR.agf", n, AGF_EXAMPLES)


@pytest.mark.parametrize("n", SIZES)
def test_lens_toml_reader(n, tmp_path):
    strategy = st.one_of(mutated(LENS_TOML, toml=True), toml_tree(_tomls(LENS_TOML)))
    _fuzz("lens.toml", strategy, load_lens, tmp_path / "lens.toml", n, LENS_TOML_EXAMPLES)


@pytest.mark.parametrize("n", SIZES)
def test_mount_toml_reader(n, tmp_path):
    strategy = st.one_of(mutated(MOUNT_TOML, toml=True), toml_tree(_tomls(MOUNT_TOML)))
    _fuzz("mount.toml", strategy, load_mount, tmp_path / "mount.toml", n, MOUNT_TOML_EXAMPLES)


@pytest.mark.parametrize("n", SIZES)
def test_finishes_toml_reader(n, tmp_path):
    strategy = st.one_of(mutated(FINISHES_TOML, toml=True), toml_tree(_tomls(FINISHES_TOML)))
    _fuzz("finishes.toml", strategy, lambda p: load_finishes(p.parent), tmp_path / "finishes.toml", n,
          FINISHES_TOML_EXAMPLES)


@pytest.mark.parametrize("n", SIZES)
def test_scene_reader(n, tmp_path, example_finishes):
    strategy = st.one_of(mutated(SCENE_TOML, toml=True), toml_tree(_tomls(SCENE_TOML)))
    _fuzz("scene", strategy, lambda p: load_scene(p, example_finishes), tmp_path / "scene.toml", n,
          SCENE_EXAMPLES)


def _read_step_part(path: Path):
    """The STEP file of a `[parts.housing]` entry, read as `regenerate` reads it, and its solids' boxes."""
    from lensmount.cad.step_parts import read_entry  # lazy: the CAD kernel only for this test
    from lensmount.design.mount import parse_mount

    spec = parse_mount({"parts": {"housing": {"step": path.name}}}, file=str(path.parent / "mount.toml"))
    step = read_entry(spec, "housing", path)
    return step.unit, [tuple(s.solid.bounding_box().size) for s in step.solids]


@pytest.mark.parametrize("n", [100, pytest.param(SLOW, marks=pytest.mark.slow)])
def test_step_part_reader(n, tmp_path):
    pytest.importorskip("build123d")
    _fuzz("STEP part", mutated(STEP), _read_step_part, tmp_path / "housing.step", n, STEP_EXAMPLES)


# ---------------------------------------------------------------- through the CLI

def _inspect_once(folder: Path, name: str, data: bytes) -> int:
    folder.mkdir(exist_ok=True)
    for f in folder.iterdir():
        f.unlink()
    (folder / name).write_bytes(data)
    res = CliRunner().invoke(app, ["inspect", str(folder / name)])
    assert res.exit_code in (0, 2), (res.exit_code, res.output, res.exception)
    assert "Traceback" not in res.output
    if res.exit_code == 2:
        errors = [line for line in res.output.splitlines() if line.startswith("error: ")]
        assert len(errors) == 1 and res.output.rstrip().endswith(errors[0]), res.output
        assert str(folder / name) in errors[0]
    assert sorted(f.name for f in folder.iterdir()) == [name]  # nothing written
    return res.exit_code


@pytest.mark.parametrize("n", [60, pytest.param(2000, marks=pytest.mark.slow)])
@pytest.mark.parametrize("name", ["lens.zmx", "lens.toml"])
def test_inspect_reads_malformed_lenses_as_one_paragraph(name, n, tmp_path):
    seeds = ZMX if name.endswith(".zmx") else LENS_TOML
    strategy = (st.one_of(mutated(seeds), keyword_lines(seeds, ZMX_KEYWORDS)) if name.endswith(".zmx")
                else st.one_of(mutated(seeds, toml=True), toml_tree(_tomls(seeds))))
    codes: Counter = Counter()

    @settings(max_examples=n, derandomize=True, database=None, deadline=None, suppress_health_check=list(HealthCheck))
    @given(strategy)
    def run(data):
        codes[_inspect_once(tmp_path / "in", name, data)] += 1

    run()
    print(f"\ninspect {name}: {sum(codes.values())} inputs (exit 0: {codes[0]}, exit 2: {codes[2]})")
    assert sum(codes.values()) >= n


# ---------------------------------------------------------------- what the fuzzing found (regression inputs)

ZMX_EXAMPLES = [  # damaged UTF-16 was a UnicodeDecodeError
    b"\xff\xfeV\x00E\x00R\x00S\x00\n",  # with a BOM, an odd byte count (truncated)
    b"\x00S\x00U\x00R\x00F\x00 \x000\x00\n" * 4 + b"\x00",  # without a BOM
    b"\xff\xfe\x00\xd8S\x00U\x00R\x00F\x00",  # a lone surrogate
    ZMX[0].replace(b"DISZ INFINITY", b"DISZ 0", 1),  # the object in the entrance pupil: a ZeroDivisionError
    ZMX[0].replace(b"SURF 1", b"SURF nan", 1),  # int(nan): a ValueError
    ZMX[0].replace(b"SURF 1", b"SURF 1e400", 1),  # int(inf): an OverflowError
    b"SURF 0\nSURF 1\nTYPE XASPHERE\nXDAT 1 1e18\nXDAT 2 1\nSURF 2\n",  # 10^18 terms: no end
    b"SURF 0\nSURF 1\nTYPE EVENASPH\nPARM 1e15 1\nSURF 2\n",  # an r^(2 10^15) term: no end
]
AGF_EXAMPLES = [
    AGF.replace(b"NM MYCROWN 2", b"NM MYCROWN nan", 1),  # int(nan): a ValueError
    AGF.replace(b"1.5301", b"nan", 1),  # a NaN n_d loaded
]
LENS_TOML_EXAMPLES = [  # NaN loaded into the Prescription
    LENS_TOML[-1].replace(b"weights = [1.0, 1.0, 1.0]", b"weights = [nan, 1.0, 1.0]", 1),
]
MOUNT_TOML_EXAMPLES = [b"[vanes]\npositions_mm = [nan]\n"]  # a NaN vane position loaded
FINISHES_TOML_EXAMPLES = [b"\xa3 finishes.toml\n[finishes]\n"]  # not UTF-8: was a UnicodeDecodeError
SCENE_EXAMPLES = [
    b'[source]\ntype = ["sun"]\n',  # a list as the type: a TypeError (unhashable)
    SCENE_TOML[0].replace(b"azimuth_deg = 90.0", b"azimuth_deg = nan", 1),  # a NaN azimuth loaded
]
STEP_EXAMPLES = [  # broken entities: OCC's transfer crashed the process (a segmentation fault)
    STEP[0].replace(b"#18=CYLINDRICAL_SURFACE('',#680,17.5);", b"#18=CYLINDRICAL_SURFACE('',#60.0,17.5);", 1)
    .replace(b"#74=FACE_OUTER_BOUND('',#114,.T.);", b"#74=FACE_OUTER_BOUND('',#1CM,.T.);", 1),
    # an instance name beyond 32 bits: OCC's reader itself crashed
    STEP[0].replace(b"#175=LINE('',#998,#243);", b"#12106238143296=LINE('',#998,#243);", 1),
]
