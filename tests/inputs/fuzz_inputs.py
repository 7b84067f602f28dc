"""Malformed inputs a user could write, as Hypothesis strategies, for `test_fuzz_readers`.

Two kinds per format: real files mutated (byte flips, truncation, lines deleted or duplicated, numbers
replaced by extreme, NaN, infinite or negative values, keys renamed, values of another type), and
files generated from the format's structure (TOML: the real file's tables with typed values dropped,
renamed, retyped or added; Zemax and .agf: lines of the format's keywords with arguments).
"""

from __future__ import annotations

import re

import tomli_w
from hypothesis import strategies as st

NUMBER = re.compile(rb"(?<![A-Za-z_#])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
TOML_KEY = re.compile(rb"^([ \t]*)([A-Za-z0-9_\-]+|\"[^\"\n]*\")([ \t]*=)", re.M)
TOML_VALUE = re.compile(rb"(=[ \t]*)([^\n#]*)")
WORD = re.compile(rb"^[ \t]*([A-Z]{2,4})\b", re.M)

EXTREME = [b"nan", b"NaN", b"-nan", b"inf", b"-inf", b"INFINITY", b"1e308", b"-1e308", b"1e309", b"5e-324", b"0",
           b"-0", b"0.0", b"-1", b"-1e-9", b"1e-300", b"99999999999999999999999999", b"-7", b"1e30", b"2147483648",
           b"-2147483649", b"1.7976931348623157e+308", b"0x10", b"1_000", b"1.", b".5", b"+3"]
OTHER_TYPE = [b'"text"', b'""', b"true", b"false", b"[]", b"[1, 2]", b'["a", 1.5]', b"{}", b"{ a = 1 }", b"nan", b"inf",
              b"-inf", b"1979-05-27", b"07:32:00", b"-3", b"0", b'"nan"', b"[[1], [2]]", b"1e400", b"'lit'"]
ZMX_KEYWORDS = ["SURF", "TYPE", "CURV", "CONI", "PARM", "DISZ", "GLAS", "DIAM", "CLAP", "MEMA", "OEMA", "STOP", "COAT",
                "COMM", "PZUP", "XDAT", "UNIT", "MODE", "NAME", "ENPD", "FNUM", "OBNA", "FLOA", "WAVM", "WAVL",
                "WWGT", "PWAV", "FTYP", "YFLN", "XFLN", "YFLD", "XFLD", "VDXN", "VDYN", "VCXN", "VCYN", "VANN",
                "GCAT", "MNUM", "VERS", "HIDE", "MAZH", "FLAP"]
ZMX_WORDS = ["STANDARD", "EVENASPH", "ODDASPH", "XASPHERE", "XOSPHERE", "QED_TYPE", "COORDBRK", "PARAXIAL", "TOROIDAL",
             "N-BK7", "SF5", "MIRROR", "___BLANK", "INFINITY", "MM", "CM", "IN", "METER", "SEQ", "NSC", "SCHOTT",
             "OHARA", "AIR", "517642", "X"]
AGF_KEYWORDS = ["NM", "CD", "TD", "OD", "LD", "IT", "ED", "GC", "CC", "BD"]

_numbers = st.one_of(st.sampled_from(EXTREME), st.floats().map(lambda x: repr(x).encode()),
                     st.integers(-10 ** 20, 10 ** 20).map(lambda x: str(x).encode()))


def _lines(data: bytes) -> list[bytes]:
    return data.split(b"\n")


@st.composite
def mutated(draw, seeds: list[bytes], toml: bool = False):
    """A seed file with 1–4 mutations."""
    data = draw(st.sampled_from(seeds))
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["flip", "truncate", "delete", "duplicate", "number", "key", "type", "byte"]))
        if not data:
            break
        if op == "flip":
            i = draw(st.integers(0, len(data) - 1))
            data = data[:i] + bytes([data[i] ^ (1 << draw(st.integers(0, 7)))]) + data[i + 1:]
        elif op == "byte":
            i = draw(st.integers(0, len(data) - 1))
            data = data[:i] + draw(st.binary(min_size=1, max_size=3)) + data[i + 1:]
        elif op == "truncate":
            data = data[:draw(st.integers(0, len(data) - 1))]
        elif op in ("delete", "duplicate"):
            lines = _lines(data)
            i = draw(st.integers(0, len(lines) - 1))
            lines[i:i + 1] = [] if op == "delete" else [lines[i], lines[i]]
            data = b"\n".join(lines)
        elif op == "number":
            found = list(NUMBER.finditer(data))
            if found:
                m = found[draw(st.integers(0, len(found) - 1))]
                data = data[:m.start()] + draw(_numbers) + data[m.end():]
        elif op == "key":
            found = list((TOML_KEY if toml else WORD).finditer(data))
            if found:
                m = found[draw(st.integers(0, len(found) - 1))]
                g = 2 if toml else 1
                old = m.group(g)
                keys = [k.group(g) for k in found]
                new = draw(st.one_of(st.sampled_from(keys), st.just(old[:-1] or b"x"), st.just(old + b"s"),
                                     st.just(old.upper() if toml else old.lower()),
                                     st.sampled_from([w.encode() for w in (ZMX_KEYWORDS if not toml else ["x"])])))
                data = data[:m.start(g)] + new + data[m.end(g):]
        elif op == "type":
            found = list(TOML_VALUE.finditer(data)) if toml else list(NUMBER.finditer(data))
            if found:
                m = found[draw(st.integers(0, len(found) - 1))]
                g = 2 if toml else 0
                data = data[:m.start(g)] + draw(st.sampled_from(OTHER_TYPE if toml else
                                                               [w.encode() for w in ZMX_WORDS])) + data[m.end(g):]
    return data


_keys = st.text("abcdefghijklmnopqrstuvwxyz_-0123456789", min_size=1, max_size=12)
_leaf = st.one_of(st.floats(), st.sampled_from([float("nan"), float("inf"), -float("inf"), 0.0, -0.0, 1e308, -1.0]),
                  st.integers(-2 ** 70, 2 ** 70), st.text(max_size=12), st.booleans())
_value = st.recursive(_leaf, lambda inner: st.lists(inner, max_size=4) | st.dictionaries(_keys, inner, max_size=3),
                      max_leaves=6)


@st.composite
def toml_tree(draw, bases: list[dict]):
    """A real file's tables with keys dropped, renamed or added and values retyped or replaced, as TOML."""
    known = sorted({k for base in bases for k in _all_keys(base)})
    key_names = st.one_of(st.sampled_from(known), _keys) if known else _keys

    def walk(node):
        if isinstance(node, dict):
            out = {}
            for k, v in node.items():
                r = draw(st.integers(0, 11))
                if r == 0:
                    continue
                out[draw(key_names) if r == 1 else k] = draw(_value) if r == 2 else walk(v)
            if draw(st.integers(0, 7)) == 0:
                out[draw(key_names)] = draw(_value)
            return out
        if isinstance(node, list):
            items = [walk(x) for x in node]
            if items and draw(st.integers(0, 5)) == 0:
                del items[draw(st.integers(0, len(items) - 1))]
            return items
        if isinstance(node, (int, float)) and not isinstance(node, bool) and draw(st.integers(0, 3)) == 0:
            return draw(st.one_of(st.floats(), st.sampled_from([float("nan"), float("inf"), -float("inf"), 0, -1,
                                                                   -1e-9, 1e308, 2 ** 64])))
        return node

    tree = walk(draw(st.sampled_from(bases)))
    return tomli_w.dumps(tree).encode()


def _all_keys(node):
    if isinstance(node, dict):
        for k, v in node.items():
            yield k
            yield from _all_keys(v)
    elif isinstance(node, list):
        for x in node:
            yield from _all_keys(x)


_arg = st.one_of(_numbers, st.sampled_from([w.encode() for w in ZMX_WORDS]),
                 st.integers(-3, 12).map(lambda i: b"%d" % i))


@st.composite
def keyword_lines(draw, seeds: list[bytes], keywords: list[str]):
    """A seed file with lines replaced or inserted: a keyword of the format and 0–6 arguments."""
    lines = _lines(draw(st.sampled_from(seeds)))
    for _ in range(draw(st.integers(1, 6))):
        line = b" ".join([draw(st.sampled_from(keywords)).encode(), *draw(st.lists(_arg, max_size=6))])
        i = draw(st.integers(0, len(lines)))
        if draw(st.booleans()) and i < len(lines):
            lines[i] = b"  " + line
        else:
            lines.insert(i, line)
    return b"\n".join(lines)


__all__ = ["mutated", "toml_tree", "keyword_lines", "ZMX_KEYWORDS", "AGF_KEYWORDS"]
