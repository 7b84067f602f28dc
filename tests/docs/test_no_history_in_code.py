"""Code and tests say what they check, not which ticket led to them: no ticket number (the word "issue"
followed by a number, in any of its usual spellings) in any text file under src/ or tests/. History belongs in CHANGELOG.md and in
commit messages. A hit fails with the file, the line and the words found."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TICKET = re.compile(r"\bissues?[\s#-]*\d+", re.IGNORECASE)


def ticket_mentions(text: str):
    """(line number, words) of each ticket number in a text."""
    return [(n, m.group()) for n, line in enumerate(text.splitlines(), 1) for m in TICKET.finditer(line)]


def test_no_ticket_numbers_in_src_or_tests():
    found = []
    for folder in ("src", "tests"):
        for path in sorted((ROOT / folder).rglob("*")):
            if not path.is_file() or "__pycache__" in path.parts:
                continue
            try:
                text = path.read_text(encoding="utf-8")
            except UnicodeDecodeError:
                continue  # binary data
            found += [f"{path.relative_to(ROOT)}:{n}: {words!r}" for n, words in ticket_mentions(text)]
    assert not found, "say what the code checks instead:\n" + "\n".join(found)


def test_the_pattern_finds_ticket_numbers_in_their_usual_spellings():
    # Written with {n} for the number, so this file holds no ticket number itself.
    text = "a (issue {n})\nIssue {n}, item 8a\nissues {n}/29\nissue-{n} script\nIssue #{n}\nthe issue's note\nissue count"
    text = text.format(n=28)
    assert [n for n, _ in ticket_mentions(text)] == [1, 2, 3, 4, 5]
