"""The accuracy-versus-time figures of ``workbench study`` runs, for a report and a run's index page.

A study folder is what ``workbench study rcwa|render|calibrate|fit --out DIR`` wrote; its
figures are the ``study_*.png`` files, embedded as data: URIs (the pages stay self-contained).
"""

from __future__ import annotations

import base64
import html
from pathlib import Path

from workbench.core.errors import UserInputError


def study_figures(folders: tuple[Path, ...], field: str = "--study") -> list[Path]:
    """Every folder's study_*.png files, in order; a UserInputError naming ``field`` for a
    folder that is missing or holds none."""
    figures: list[Path] = []
    for folder in folders:
        if not folder.is_dir():
            raise UserInputError("no such folder", field=field, got=str(folder))
        found = sorted(folder.glob("study_*.png"))
        if not found:
            raise UserInputError("holds no study figure (study_*.png, as `workbench study` writes)", field=field,
                                 got=str(folder))
        figures += found
    return figures


def study_sections(folders: tuple[Path, ...], field: str = "--study") -> list[tuple[str, str]]:
    """(heading, HTML) per figure: the PNG embedded, its folder and name as escaped text."""
    sections = []
    for figure in study_figures(folders, field):
        uri = "data:image/png;base64," + base64.b64encode(figure.read_bytes()).decode("ascii")
        label = html.escape(f"{figure.parent.name}/{figure.name}")
        sections.append((f"study: {figure.parent.name}/{figure.name}",
                         f"<img class='study' alt='{label}' src='{uri}' style='max-width:900px'>"))
    return sections
