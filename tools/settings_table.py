"""README's settings table, generated from the declarations (engine/settings.py).

    ./dev python tools/settings_table.py            # rewrite the table in README.md
    ./dev python tools/settings_table.py --check    # exit 1 if README.md's table is not the generated one

The table stands between the lines START and END of README.md; tests/test_settings.py fails
when it is not what the declarations generate.
"""
from __future__ import annotations

import argparse
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
START, END = "<!-- settings-table:start -->", "<!-- settings-table:end -->"
HEADER = "| setting | in Blender | CLI flag | default | range / choices | honoured by |"

def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _default(s) -> str:
    if isinstance(s.default, bool):
        text = "on" if s.default else "off"
    elif s.default is None:
        text = "the whole frame"
    elif isinstance(s.default, float):
        text = f"{s.default:.6g}"
    elif isinstance(s.default, tuple):
        text = ", ".join(map(str, s.default)) or "none"
    else:
        text = str(s.default)
    return text + (f" (Blender: {s.ui_default})" if s.ui_default is not None else "")


def _where(s, declared) -> str:
    """Where a setting's value comes from, unless it is the scene.ember property of its name."""
    if s.source == declared.EMBER:
        return f"scene.ember.{s.prop}" if s.prop else ""
    if s.source == declared.UI:
        return "scene.ember only"
    return f"Blender: {s.blender}" if s.source == declared.BLENDER else "internal"


def row(s, items: tuple = ()) -> str:
    """One setting's row: name (and where it comes from), its label in Blender, flag, default,
    range or choices with the unit, integrators. The descriptions are Blender's tooltips and
    `render.py --help`'s lines; the README keeps to what fits a table."""
    from ember.engine import settings as declared

    where = _where(s, declared)
    unit = declared.UNITS.get(s.unit, "")
    cells = (f"`{s.name}`" + (f" ({where})" if where else ""), s.label, f"`{s.flag}`" if s.flag else "",
             _default(s), declared.range_text(s, items) + (f" {unit}" if unit else ""),
             ", ".join(s.honoured_by) or "all")
    return "| " + " | ".join(_cell(c) for c in cells) + " |"


def table() -> str:
    """The markdown between START and END: one table per group of settings."""
    from ember.engine import settings as declared
    from ember.engine.integrators import items

    parts = []
    for g in declared.GROUPS:
        lines = [f"**{g.label}**", "", HEADER, "|" + "---|" * 6]
        lines += [row(s, items(s) if s.kind is str else ()) for s in g.settings]
        parts.append("\n".join(lines))
    return "\n\n".join(parts)


def updated(text: str) -> str:
    """README text with the table between its markers replaced by the generated one."""
    start, end = text.index(START) + len(START), text.index(END)
    return text[:start] + "\n" + table() + "\n" + text[end:]


def main() -> int:
    sys.path.insert(0, str(ROOT))
    from _bootstrap import load_ember
    load_ember()
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--check", action="store_true", help="only check that README.md's table is up to date")
    args = p.parse_args()
    text = README.read_text()
    new = updated(text)
    if args.check:
        if new != text:
            print("README.md's settings table is out of date: ./dev python tools/settings_table.py", file=sys.stderr)
            return 1
        return 0
    README.write_text(new)
    return 0


if __name__ == "__main__":
    sys.exit(main())
