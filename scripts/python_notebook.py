#!/usr/bin/env python3
"""Writes docs/python_tutorial.ipynb from docs/python.md's "Tutorial" section: each Python
block a code cell, the text between them markdown cells (the notebook and the page hold the
same code; tests/python/tutorial_test.py checks that).

Usage: scripts/python_notebook.py [--check]   (--check: exit 1 when the notebook differs)
"""
import json
import os
import re
import sys

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
PAGE = os.path.join(ROOT, "docs", "python.md")
NOTEBOOK = os.path.join(ROOT, "docs", "python_tutorial.ipynb")


def tutorial_cells(page_text):
    """[(kind, source)] of the page's Tutorial section, kind 'code' or 'markdown'."""
    start = page_text.index("## Tutorial")
    end = page_text.find("\n## ", start + 1)
    section = page_text[start:end if end >= 0 else None]
    cells = []
    pos = 0
    for m in re.finditer(r"```python\n(.*?)```\n", section, re.S):
        text = section[pos:m.start()].strip()
        if text:
            cells.append(("markdown", text))
        cells.append(("code", m.group(1).rstrip("\n")))
        pos = m.end()
    tail = section[pos:].strip()
    if tail:
        cells.append(("markdown", tail))
    return cells


def notebook(cells):
    def lines(s):
        parts = s.split("\n")
        return [p + "\n" for p in parts[:-1]] + [parts[-1]]

    out = []
    for i, (kind, source) in enumerate(cells):
        # nbformat 4.5: every cell has an id (stable, so that the file only changes with the page).
        cell = {"cell_type": kind, "id": f"cell-{i:02d}", "metadata": {}, "source": lines(source)}
        if kind == "code":
            cell.update({"execution_count": None, "outputs": []})
        out.append(cell)
    return {
        "cells": out,
        "metadata": {
            "kernelspec": {"display_name": "Python 3 (Debian)", "language": "python", "name": "python3"},
            "language_info": {"name": "python"},
        },
        "nbformat": 4,
        "nbformat_minor": 5,
    }


def text(nb):
    return json.dumps(nb, indent=1, ensure_ascii=False) + "\n"


def main():
    with open(PAGE, encoding="utf-8") as f:
        wanted = text(notebook(tutorial_cells(f.read())))
    if "--check" in sys.argv[1:]:
        with open(NOTEBOOK, encoding="utf-8") as f:
            if f.read() != wanted:
                print(f"{NOTEBOOK} differs from {PAGE}: run scripts/python_notebook.py", file=sys.stderr)
                return 1
        return 0
    with open(NOTEBOOK, "w", encoding="utf-8") as f:
        f.write(wanted)
    return 0


if __name__ == "__main__":
    sys.exit(main())
