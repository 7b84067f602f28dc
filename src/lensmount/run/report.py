"""report.html: one self-contained page per run, per comparison and per PST sweep.

An engineer hands the page round by e-mail or opens it on a laptop in a train, so it
carries everything inline: images as base64 PNG, a few lines of CSS, no scripts, no
fonts, no links to fetch. What it shows comes from summary.json and the images the
run wrote; it computes nothing of its own, so the page and the JSON never disagree.

Summary keys read (all optional except `stray_fraction`): `method`, `passes`, `photons`,
`time_s`, `stray_fraction_std_error`, `stray_fraction_rel_error`,
`stray_fraction_bias_bound`, `per_part` ({name: {fraction, std_error, bias_bound}}),
and for provenance every other scalar (input hashes, git commit, version, command).
"""

from __future__ import annotations

import base64
import html
import math
import os
from pathlib import Path

from lensmount.atomic import write_text

# Keys the headline and the part table show; every other scalar goes to "Inputs and provenance".
_SHOWN = {"stray_fraction", "stray_fraction_std_error", "stray_fraction_rel_error", "stray_fraction_bias_bound",
          "stray_fraction_bias_unbounded",
          "per_part", "units", "method", "passes", "photons", "time_s"}

_CSS = """
body{font-family:system-ui,sans-serif;margin:2em auto;max-width:60em;color:#222;padding:0 1em}
h1{font-size:1.4em}h2{font-size:1.1em;margin-top:1.6em;border-bottom:1px solid #ccc}
table{border-collapse:collapse;font-size:.9em}td,th{padding:.2em .8em;border-bottom:1px solid #eee;text-align:right}
td:first-child,th:first-child{text-align:left}figure{display:inline-block;margin:.5em}
td{overflow-wrap:anywhere}th{overflow-wrap:normal;hyphens:none}tr.differs td{background:#fff3cd}tr.differs td:first-child{font-weight:bold}
figcaption{font-size:.85em;color:#555}img{max-width:100%}
.verdict{font-size:1.2em;font-weight:bold;padding:.5em;border:2px solid #888;display:inline-block}
.regression{border-color:#c00;color:#c00}.ok{border-color:#080;color:#080}.undecided{border-color:#b80;color:#b80}
code{font-size:.85em;word-break:break-all}
"""


def esc(value) -> str:
    return html.escape(str(value), quote=True)


def fmt(value, error=None) -> str:
    """value ± error with the digits the error justifies; '—' for unknown."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    if error is None or not math.isfinite(float(error)):
        return f"{value:.4g}"
    return f"{value:.4g} ± {error:.2g}"


def image_block(caption: str, png: bytes | str | os.PathLike) -> str:
    """A figure with the PNG inline as a data URI (bytes, or the path of a PNG file)."""
    data = png if isinstance(png, bytes) else Path(png).read_bytes()
    uri = "data:image/png;base64," + base64.b64encode(data).decode("ascii")
    return f'<figure><img src="{uri}" alt="{esc(caption)}"><figcaption>{esc(caption)}</figcaption></figure>'


def table_block(headers: list[str], rows: list[list], caption: str = "", marked: set[int] = frozenset()) -> str:
    """A table; rows whose index is in `marked` get class "differs" (highlighted). Long cells
    (hashes, paths, command lines) wrap anywhere, so the page keeps its width."""
    head = "".join(f"<th>{esc(h)}</th>" for h in headers)
    body = "".join(("<tr class=\"differs\">" if i in marked else "<tr>") + "".join(f"<td>{esc(c)}</td>" for c in row)
                   + "</tr>" for i, row in enumerate(rows))
    cap = f"<caption>{esc(caption)}</caption>" if caption else ""
    return f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def section(title: str, *blocks: str) -> str:
    return f"<h2>{esc(title)}</h2>" + "".join(blocks)


def page(title: str, blocks: list[str], refresh_s: float | None = None) -> str:
    """The whole document. No external resource of any kind (checked by the browser test);
    refresh_s: the browser reloads the page that often (`lensmount watch`'s live page)."""
    refresh = f"<meta http-equiv=\"refresh\" content=\"{refresh_s:g}\">" if refresh_s else ""
    return ("<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">" + refresh +
            "<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; img-src data:; "
            "style-src 'unsafe-inline'\">"
            f"<title>{esc(title)}</title><style>{_CSS}</style></head><body><h1>{esc(title)}</h1>"
            + "".join(blocks) + "</body></html>\n")


def headline_rows(summary: dict) -> list[list]:
    rows = [["stray fraction", fmt(summary.get("stray_fraction"), summary.get("stray_fraction_std_error"))]]
    rel = summary.get("stray_fraction_rel_error")
    rows.append(["relative standard error", f"{100 * rel:.2f} %" if rel is not None else "—"])
    if summary.get("stray_fraction_bias_bound") is not None:
        rows.append(["bias bound", fmt(summary["stray_fraction_bias_bound"])])
    if summary.get("stray_fraction_bias_unbounded"):
        rows.append(["bias bound", f"none: {summary['stray_fraction_bias_unbounded']}"])
    for key, label in (("method", "method"), ("passes", "passes"), ("photons", "photons"), ("time_s", "time (s)")):
        if summary.get(key) is not None:
            rows.append([label, f"{summary[key]:,}" if isinstance(summary[key], int) else summary[key]])
    return rows


def part_rows(per_part: dict) -> tuple[list[str], list[list]]:
    """Parts that carry stray light, largest first: fraction ± error, share, bias bound if any."""
    lit = sorted(((v.get("fraction") or 0.0, name, v) for name, v in per_part.items() if (v.get("fraction") or 0) > 0),
                 key=lambda t: t[0], reverse=True)
    total = sum(f for f, _, _ in lit) or 1.0
    with_bias = any(v.get("bias_bound") is not None for _, _, v in lit)
    headers = ["part", "stray fraction ± std. error", "share"] + (["bias bound"] if with_bias else [])
    rows = [[name, fmt(f, v.get("std_error")), f"{100 * f / total:.1f} %"]
            + ([fmt(v.get("bias_bound"))] if with_bias else []) for f, name, v in lit]
    return headers, rows


def path_rows(top_paths: dict) -> list[list]:
    """`summary.json`'s top_paths as rows: rank, events in order, fraction ± error, share."""
    rows = [[str(r["rank"]), " → ".join(e["name"] for e in r["events"]), fmt(r["fraction"], r["std_error"]),
             "—" if r.get("share") is None else f"{100 * r['share']:.1f} %"] for r in top_paths.get("paths", [])]
    other = top_paths.get("other") or {}
    if other.get("paths"):
        rows.append(["", f"{other['paths']} other paths", fmt(other.get("fraction"), other.get("std_error")), ""])
    return rows


def face_rows(faces: dict) -> list[list]:
    """Critical ∩ illuminated faces as rows: CAD face, role, finish, area, E, G, G·E/π."""
    return [[str(k), f"{r['part']} face {r['face']}", r["role"], r["finish"], fmt(r["area_mm2"]), fmt(r["irradiance"]),
             fmt(r["etendue_mm2_sr"]), fmt(r["product_fraction"])]
            for k, r in enumerate(faces.get("critical_and_illuminated", []), 1)]


def provenance_rows(summary: dict) -> list[list]:
    """Every scalar the summary carries beyond the figures (hashes, commit, version, command),
    flattening one level of nested tables such as {"hashes": {"lens": ...}}."""
    def shown(v):
        if v is None:
            return "—"
        return f"{v:.6g}" if isinstance(v, float) else v

    rows = []
    for key in sorted(summary):
        if key in _SHOWN:
            continue
        value = summary[key]
        if isinstance(value, dict):
            rows += [[f"{key}.{k}", shown(v)] for k, v in sorted(value.items()) if not isinstance(v, (dict, list))]
        elif isinstance(value, list):
            if all(not isinstance(v, (dict, list)) for v in value):
                rows.append([key, " ".join(str(v) for v in value)])
        else:
            rows.append([key, shown(value)])
    return rows


def run_blocks(summary: dict, images: dict[str, bytes | str | os.PathLike]) -> list[str]:
    """Headline figures, images, the per-part table and provenance of one run."""
    blocks = [section("Result", table_block(["", ""], headline_rows(summary)))]
    if images:
        blocks.append(section("Images", *(image_block(c, p) for c, p in images.items())))
    headers, rows = part_rows(summary.get("per_part", {}))
    if rows:
        blocks.append(section("Stray fraction by part (last scattering surface)", table_block(headers, rows)))
    paths = path_rows(summary.get("top_paths") or {})
    if paths:
        blocks.append(section("Paths carrying most stray light (scatter events in order; `lensmount paths`)",
                              table_block(["rank", "events", "stray fraction ± std. error", "share"], paths)))
    faces = face_rows(summary.get("faces") or {})
    if faces:
        blocks.append(section("Faces seen by the detector and lit by the source (`lensmount paths --faces`)",
                              table_block(["rank", "CAD face", "role", "finish", "area mm²", "E/E_sun", "G mm²·sr",
                                           "G·E/π / aperture flux"], faces)))
    blocks.append(section("Inputs and provenance", table_block(["field", "value"], provenance_rows(summary))))
    return blocks


def run_report(summary: dict, images: dict[str, bytes | str | os.PathLike], title: str | None = None) -> str:
    prov = summary.get("provenance") or {}
    name = prov.get("design_name") or Path(str(summary.get("design", "run"))).name
    scene = prov.get("scene_name") or Path(str(summary.get("scene", ""))).stem
    return page(title or f"lensmount run · {name}" + (f" · {scene}" if scene else ""), run_blocks(summary, images))


def comparison_report(old: dict, new: dict, verdict: str, rows: list[list], headers: list[str],
                      images: dict[str, bytes | str | os.PathLike], detail: str = "",
                      kind: str = "undecided") -> str:
    """The page for `compare`: the verdict first, then the change per part, the images on one
    scale, and both runs' provenance side by side.

    verdict : the sentence `compare` prints (e.g. "regression: +205 % ± 24 % (99 % confidence)")
    rows, headers : the change table as `compare` prints it
    kind : "regression" | "ok" | "undecided" (the colour of the verdict box)
    """
    blocks = [f'<p class="verdict {esc(kind)}" id="verdict">{esc(verdict)}</p>']
    if detail:
        blocks.append(f"<p>{esc(detail)}</p>")
    blocks.append(section("Change", table_block(headers, rows)))
    if images:
        blocks.append(section("Images (one colour scale and pixel binning for both runs)",
                              *(image_block(c, p) for c, p in images.items())))
    prov_old, prov_new = dict(provenance_rows(old)), dict(provenance_rows(new))
    keys = sorted(set(prov_old) | set(prov_new))
    rows = [[k, prov_old.get(k, "—"), prov_new.get(k, "—")] for k in keys]
    differ = {i for i, (_, a, b) in enumerate(rows) if a != b}
    rows = [["≠ " + r[0] if i in differ else r[0], *r[1:]] for i, r in enumerate(rows)]
    blocks.append(section("Inputs and provenance", table_block(
        ["field", "old", "new"], rows, f"{len(differ)} field(s) differ, marked ≠ and highlighted", differ)))
    return page("lensmount comparison", blocks)


def write_report(path: str | os.PathLike, document: str) -> Path:
    """Write the page atomically (a reader never sees half a report)."""
    write_text(path, document)
    return Path(path)


__all__ = ["run_report", "comparison_report", "write_report", "page", "section", "image_block", "table_block",
           "run_blocks", "provenance_rows", "fmt", "path_rows", "face_rows"]
