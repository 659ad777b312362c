"""The efficiency tables behind a report, and the truncation error each records (issue 29, item 3).

Which tables: those the render read (its sidecar's ``tables``, when the sidecar describes
that very EXR: renderer.render.described_render) and the one the grating-equation
prediction weighed its orders with (renderer.trace.efficiency_weights). For each, report.json's
``tables`` and the page's "efficiency tables" section give what the table records of its
own truncation error (rcwa.table.truncation.summary): at a sample of its nodes, the same
solve at about half the retained orders and, for a 2D cell, with the other factorization
rule; the largest difference in the kept orders' efficiencies, where it occurs, and per
wavelength. A table built before tables recorded it says "not recorded" (its error is
unknown, not zero), and so does the page's notes.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rcwa.table import read_table_metadata, truncation_summary
from rcwa.table.store import read_progress
from renderer.render import described_render
from reports.page import html as page
from workbench.core.errors import UserInputError

NOT_RECORDED = "not recorded"
TABLE_TIPS = {
    "table": "the efficiency table's folder (rcwa.table)",
    "used by": "render: the sidecar of this very render names it; prediction: the grating-equation prediction's order "
               "weights",
    "vs lower truncation": "largest |difference| in a kept order's efficiency between the table's solve and the same "
                           "solve at about half its retained orders, over the sampled nodes (rcwa.table.truncation)",
    "vs other rule": "the same against the other factorization rule (2D cells: Li's rule and the normal-vector method)",
    "recorded": "wavelengths with a record, of the table's; 'not recorded': built before tables recorded it",
}


def report_tables(render: Path, prediction_table: str | None) -> list[dict[str, Any]]:
    """report.json's ``tables``: one entry per table the render or the prediction read (table_entry)."""
    used: dict[str, list[str]] = {}
    for path in (described_render(render) or {}).get("tables") or []:
        used.setdefault(str(path), []).append("render")
    if prediction_table:
        used.setdefault(str(prediction_table), []).append("prediction")
    return [table_entry(Path(path), by) for path, by in used.items()]


def table_entry(path: Path, used_by: list[str]) -> dict[str, Any]:
    """What ``path`` records of its truncation error: ``status`` "recorded" with the largest
    differences and the per-wavelength ones, "not recorded", or why it cannot be read."""
    entry: dict[str, Any] = {"path": str(path), "used_by": used_by}
    try:
        meta = read_table_metadata(path)
    except UserInputError as error:
        return entry | {"status": f"not readable: {error.reason}"}
    entry |= {"structure": meta.get("structure_name"), "orders": meta["settings"]["orders"],
              "rule": meta.get("factorization")}
    info = truncation_summary(meta, None if meta.get("complete") else read_progress(path))
    if info is None:
        return entry | {"status": NOT_RECORDED}
    per_wavelength = [{"wavelength_nm": wl, "vs_lower_truncation": _largest(r, "truncation"),
                       "vs_other_rule": _largest(r, "factorization")}
                      for wl, r in zip(info["wavelengths_nm"], info["wavelengths"], strict=True) if r is not None]
    return entry | {"status": "recorded", "wavelengths_recorded": info["wavelengths_recorded"],
                    "wavelengths_total": info["wavelengths_total"], "largest_vs_lower_truncation": info["truncation"],
                    "largest_vs_other_rule": info["factorization"], "sample_share_of_build": info["sample_share"],
                    "per_wavelength": per_wavelength}


def _largest(record: dict, key: str) -> float | None:
    found = record.get(key)
    return None if not found else float(found["max_difference"])


def unrecorded_messages(entries: list[dict[str, Any]]) -> list[str]:
    """The page's notes for tables whose truncation error is not recorded or that cannot be read."""
    out = []
    for e in entries:
        if e["status"] == NOT_RECORDED:
            out.append(f"efficiency table {e['path']}: its truncation error is not recorded (built before tables "
                       "recorded it), so its error is unknown; building it again records it")
        elif e["status"].startswith("not readable"):
            out.append(f"efficiency table {e['path']}: {e['status']}")
    return out


def tables_html(entries: list[dict[str, Any]]) -> str:
    """The page's "efficiency tables" section: one row per table."""
    if not entries:
        return "<p class='none'>no efficiency table: the render's sidecar names none and the prediction read none</p>"
    rows = []
    for e in entries:
        status = e["status"]
        if status == "recorded":
            other = (_where(e["largest_vs_other_rule"]) if len(e["orders"]) > 1
                     else "- (1D: Li's rule is the normal-vector method)")
            errors = [_where(e["largest_vs_lower_truncation"]), other,
                      f"{e['wavelengths_recorded']} of {e['wavelengths_total']} wavelengths"]
        else:
            errors = [status, NOT_RECORDED if status == NOT_RECORDED else "-", "-"]
        rows.append({"table": Path(e["path"]).name, "used by": ", ".join(e["used_by"]), "structure": e.get("structure"),
                     **dict(zip(("vs lower truncation", "vs other rule", "recorded"), errors, strict=True))})
    return page.table(rows, caption="each table's own truncation error, largest over its sampled nodes",
                      tips=TABLE_TIPS)


def _where(worst: dict | None) -> str:
    """The largest difference and where it occurs, as text (- where none was compared)."""
    if not worst:
        return "-"
    against = ("x".join(map(str, worst["lower_orders"])) + " orders" if "lower_orders" in worst
               else f"{worst['other_rule']} rule")
    return (f"{worst['max_difference']:.2e} against {against}: {worst['array']} order ({worst['order'][0]}, "
            f"{worst['order'][1]}) {worst['pol']} at {worst['wavelength_nm']:g} nm, theta {worst['theta_deg']:g}, "
            f"phi {worst['phi_deg']:g} deg")
