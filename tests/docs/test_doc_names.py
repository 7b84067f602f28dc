"""Every lensmount name the docs mention exists: README.md and docs/**/*.md are read, each dotted name
is imported (the longest importable module prefix, then attribute by attribute), and a name that does
not resolve fails with the doc, the line and the name.

A name counts when it is written `lensmount.x.y` anywhere, or, inside code (a `code span` or a fenced
block), when its first part is one of lensmount's own folders or top-level modules (`cad.layout.Envelope`,
`physics.bsdf.MODELS`). File names (`mesh.npz`, `summary.json`) and paths (`cli/simulate.py`) are not names.
A class attribute counts when the class has it, declares it (dataclass, pydantic or annotated field) or
sets it on `self` in its source.
"""

import importlib
import inspect
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "src" / "lensmount"
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]

TOP_LEVEL = sorted(
    {p.parent.name for p in PACKAGE.glob("*/__init__.py")}
    | {p.stem for p in PACKAGE.glob("*.py") if p.stem != "__init__"}
)
FILE_SUFFIXES = {
    "py", "toml", "json", "npz", "npy", "exr", "png", "svg", "dxf", "csv", "html", "sqlite", "zmx", "agf",
    "md", "bsdf", "txt", "step", "stp", "yml", "yaml", "log", "pdf", "gz", "cfg", "ini", "nbi", "nbc",
}
_WORD = r"[A-Za-z_]\w*"
# Not after a word, a dot, a slash or a bracket: `out/scene.toml`, `self.scene.build` and `f(x).run` are no names.
_START = r"(?<![\w./\\)\]-])"
PREFIXED = re.compile(_START + rf"lensmount(?:\.{_WORD})+")
BARE = re.compile(_START + rf"(?:{'|'.join(TOP_LEVEL)})(?:\.{_WORD})+")
CODE_SPAN = re.compile(r"`([^`]+)`")


def _is_file_name(name: str) -> bool:
    return name.rsplit(".", 1)[-1].lower() in FILE_SUFFIXES


def mentions(text: str):
    """(line number, name) of every lensmount name in a markdown text."""
    lines = text.splitlines()
    fenced, prose, inside = [], [], False
    for line in lines:
        if line.lstrip().startswith("```"):
            inside = not inside
            fenced.append(False)
            prose.append("")
            continue
        fenced.append(inside)
        prose.append("" if inside else line)
    found = set()
    for number, line in enumerate(lines, 1):
        found.update((number, m.group()) for m in PREFIXED.finditer(line))
        if fenced[number - 1]:
            found.update((number, m.group()) for m in BARE.finditer(line))
    # Code spans may wrap onto the next line: search the prose as one text, lines counted by offset.
    joined = "\n".join(prose)
    for span in CODE_SPAN.finditer(joined):
        for m in BARE.finditer(span.group(1)):
            number = joined.count("\n", 0, span.start(1) + m.start()) + 1
            found.add((number, m.group()))
    return sorted((n, name) for n, name in found if not _is_file_name(name))


def _class_declares(cls: type, attribute: str) -> bool:
    for klass in inspect.getmro(cls):
        if attribute in getattr(klass, "__dataclass_fields__", {}) or attribute in getattr(klass, "model_fields", {}):
            return True
        if attribute in getattr(klass, "__annotations__", {}):
            return True
        try:
            source = inspect.getsource(klass)
        except (OSError, TypeError):
            continue
        if re.search(rf"self\.{attribute}\s*(?::[^=\n]+)?=[^=]", source):
            return True
    return False


def unresolved(name: str) -> str | None:
    """Why `name` (with or without the `lensmount.` prefix) does not resolve; None when it does."""
    parts = name.split(".")
    if parts[0] != "lensmount":
        parts = ["lensmount", *parts]
    module, depth = None, len(parts)
    while depth > 1:
        try:
            module = importlib.import_module(".".join(parts[:depth]))
            break
        except ModuleNotFoundError as error:
            if error.name != ".".join(parts[:depth]) and not ".".join(parts[:depth]).startswith(f"{error.name}."):
                raise  # the module exists but imports something missing: a real failure, not a doc's
            depth -= 1
    obj = module
    for i, attribute in enumerate(parts[depth:], depth):
        if hasattr(obj, attribute):
            obj = getattr(obj, attribute)
        elif inspect.isclass(obj) and _class_declares(obj, attribute):
            return None  # an instance attribute: nothing further down can be checked
        else:
            return f"{'.'.join(parts[:i])} has no {attribute!r}"
    return None


# Dotted names that are no module or attribute, each with what it is.
NOT_PYTHON_NAMES = {"lensmount.plugins": "the entry-point group a user's plug-in package declares"}


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_lensmount_name_in_the_doc_resolves(doc):
    failures = [
        f"{doc.relative_to(ROOT)}:{number}: `{name}` does not resolve ({why})"
        for number, name in mentions(doc.read_text(encoding="utf-8"))
        if name not in NOT_PYTHON_NAMES and (why := unresolved(name))
    ]
    assert not failures, "\n".join(failures)


def test_the_scan_finds_names_and_skips_files_and_paths():
    text = (
        "Prose: lensmount.cad.layout and `cad.seats.pupil_edge_radius`, not cad.layout outside code;\n"
        "`mesh.npz`, `cli/simulate.py`, `out/scene.toml`, `self.scene.build` are no names.\n"
        "```\n"
        "Scene ── trace.tracer.Tracer ─▶ Events\n"
        "```\n"
        "A span that `wraps onto\n"
        "loop.simulate.Observer` counts on its own line.\n"
    )
    assert mentions(text) == [
        (1, "cad.seats.pupil_edge_radius"),
        (1, "lensmount.cad.layout"),
        (4, "trace.tracer.Tracer"),
        (7, "loop.simulate.Observer"),
    ]


def test_names_that_do_not_exist_are_reported():
    assert unresolved("lensmount.errors.InputError") is None
    assert unresolved("mesh.FaceTag.part") is None  # a dataclass field
    assert unresolved("trace.interfaces") == "lensmount.trace has no 'interfaces'"
    assert unresolved("lensmount.errors.NoSuchError") == "lensmount.errors has no 'NoSuchError'"
    assert unresolved("mesh.FaceTag.no_such_field") == "lensmount.mesh.FaceTag has no 'no_such_field'"


def test_the_architecture_page_is_a_map():
    """At most 150 lines: the layers, what flows between them and the recipes; signatures live in the
    generated reference."""
    lines = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 150, f"docs/architecture.md has {len(lines)} lines; move detail to the docstrings"


def test_every_folder_and_module_is_in_the_generated_reference():
    """Each folder and top-level module of src/lensmount is pulled (`::: lensmount.NAME`) by a page of
    docs/reference, so a new one cannot be left out of the API reference."""
    pulled = {
        m.group(1)
        for page in (ROOT / "docs" / "reference").glob("*.md")
        for m in re.finditer(r"^::: lensmount\.(\w+)\s*$", page.read_text(encoding="utf-8"), re.MULTILINE)
    }
    assert not set(TOP_LEVEL) - pulled, f"not in docs/reference: {sorted(set(TOP_LEVEL) - pulled)}"
