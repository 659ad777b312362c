"""The order-convergence curves of rcwa.convergence, printed (``make bench``), and gold2d's converged values.

``python -m benchmarks.bench_convergence`` prints the lamellar and gold2d curves and the
gold2d accuracy-versus-time curve up to ``--max-orders`` (default 25, about a minute cold).
``--gold2d-table`` prints the converged-value table of docs/gold2d_convergence.md
(rcwa.gold2d_converged: every truncation it lists, an hour or more on 2 cores when the
raw-solve cache is cold, seconds when warm) and the reciprocity checks; ``--asr-table``
the same for adaptive spatial resolution (rcwa.asr: Li's rule, about 20 minutes cold, and the NV
rule at normal incidence, about 10 more); ``--solve-cache
FILE`` names the cache (default: rcwa.solve_cache.default_cache_path).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

from rcwa import gold2d_converged as g2
from rcwa.convergence import (
    LAMELLAR_ORDERS,
    ConvergencePoint,
    CurveConfig,
    accuracy_versus_time,
    gold2d_study,
    lamellar_tm_study,
    orders_to_reach,
)
from rcwa.solve_cache import SolveCache


def _print(points: list[ConvergencePoint], title: str) -> None:
    print(title)
    print(f"{'rule':>8} {'orders':>7} {'value':>12} {'error':>10} {'seconds':>8}")
    for p in points:
        error = f"{p.error:10.2e}" if p.error is not None else f"{'-':>10}"
        print(f"{p.rule:>8} {p.orders:>7} {p.value:12.6f} {error} {p.seconds:8.3f}")
    print()


def _print_curve(cache: SolveCache, max_orders: int) -> None:
    curve = accuracy_versus_time(cache.structure, cache, CurveConfig(max_orders=max_orders))
    print("gold2d accuracy versus time (550 nm, theta 0 and 30 deg, s and p; limits' error bars: "
          + ", ".join(f"{q} {e:.1g}" for q, e in curve["reference_errors"].items()) + ")")
    print(f"{'rule':>5} {'N':>3} {'err T_total':>11} {'err T00':>9} {'err R_total':>11} {'s/solve':>8} {'s/table':>10}")
    for r in curve["rows"]:
        mark = "~" if r["table_seconds_estimated"] else " "
        print(f"{r['rule']:>5} {r['orders']:>3} {r['error_T_total']:>11.2e} {r['error_T00']:>9.2e} "
              f"{r['error_R_total']:>11.2e} {r['seconds_per_solve']:>8.2f} {mark}{r['seconds_per_table']:>9.3g}")
    print()


def _cost_lines(values: list[g2.ConvergedValue]) -> list[str]:
    """Seconds and peak memory of one solve per truncation, at each direction (the Li and NV rules' largest)."""
    lines = ["| direction | N | seconds (li / nv) | peak memory GB (li / nv) |", "|---|---|---|---|"]
    seen = set()
    for v in values:
        if v.rule != "li" or v.quantity != "T_total" or v.pol != "s":
            continue
        nv = next(w for w in values if w.rule == "nv" and (w.wavelength_nm, w.theta_deg, w.pol, w.quantity) ==
                  (v.wavelength_nm, v.theta_deg, v.pol, v.quantity))
        for i, n in enumerate(v.orders):
            if (v.wavelength_nm, v.theta_deg, n) in seen or (n not in (9, 15, 25, 35, 41, 51, 61) and n != max(v.orders)):
                continue
            seen.add((v.wavelength_nm, v.theta_deg, n))
            gb = [f"{x / 1e9:.2f}" if x else "-" for x in (v.peak_rss_bytes[i], nv.peak_rss_bytes[i])]
            lines.append(f"| {v.wavelength_nm:g} nm, {v.theta_deg:g} deg | {n} | {v.seconds[i]:.2f} / {nv.seconds[i]:.2f} "
                         f"| {gb[0]} / {gb[1]} |")
    return lines


def _cell(v: g2.ConvergedValue) -> str:
    """``value ± error`` with the highest N and the fitted power (``!`` where the power ran to its bound)."""
    flag = "!" if v.limit.fit.power_at_bound else ""
    return f"{v.limit.value:.4f} ± {v.limit.error:.4f} (N<={max(v.orders)}, p {v.limit.fit.power:.1f}{flag})"


def gold2d_markdown(cache: SolveCache) -> str:
    """The converged-value table (markdown) and the reciprocity checks, as docs/gold2d_convergence.md shows them."""
    values = g2.converged_table(cache)
    lines = ["| nm | theta | pol | quantity | li | nv | li - nv | bars overlap |", "|---|---|---|---|---|---|---|---|"]
    for v in values:
        if v.rule != "li":
            continue
        w = next(x for x in values if x.rule == "nv" and (x.wavelength_nm, x.theta_deg, x.pol, x.quantity) ==
                 (v.wavelength_nm, v.theta_deg, v.pol, v.quantity))
        gap = v.limit.value - w.limit.value
        overlap = abs(gap) <= v.limit.error + w.limit.error
        pol = "s = p" if v.theta_deg == 0 else v.pol
        lines.append(f"| {v.wavelength_nm:g} | {v.theta_deg:g} | {pol} | {v.quantity} | {_cell(v)} | {_cell(w)} "
                     f"| {gap:+.4f} | {'yes' if overlap else 'no'} |")
    lines += ["", "Reciprocity, order (1, 0) from 30 deg against its reciprocal incidence (extrapolated over N = 9..35; "
              "'at 35': the two at N = 35):", "",
              "| nm | rule | pol | side | forward | backward | difference | within the bars | difference at 35 |",
              "|---|---|---|---|---|---|---|---|---|"]
    for c in g2.reciprocity(cache):
        lines.append(f"| {c.wavelength_nm:g} | {c.rule} | {c.pol} | {c.side} | {c.forward.value:.5f} ± {c.forward.error:.5f} "
                     f"| {c.backward.value:.5f} ± {c.backward.error:.5f} | {c.difference:.5f} | "
                     f"{'yes' if c.within_errors else 'no'} | {abs(c.forward.last_value - c.backward.last_value):.5f} |")
    return "\n".join(lines + ["", "Cost of one solve (s and p; at normal incidence s only, p by the diagonal mirror):", ""]
                     + _cost_lines(values))


def asr_markdown(cache: SolveCache) -> str:
    """Adaptive spatial resolution's converged values with Li's rule, the NV rule's beside them where
    published (g2.ASR_NV_DIRECTIONS), and reciprocity (docs/gold2d_convergence.md)."""
    nv = {(w.wavelength_nm, w.theta_deg, w.pol, w.quantity): w
          for w in g2.asr_table(cache, rule=g2.ASR_NV_RULE, only=g2.ASR_NV_DIRECTIONS)}
    lines = ["| nm | theta | pol | quantity | asr (li) | asr_nv | li - nv | value at N = 35 (li / nv) "
             "| s / solve at 35 (li / nv) |", "|---|---|---|---|---|---|---|---|---|"]
    for v in g2.asr_table(cache):
        pol = "s = p" if v.theta_deg == 0 else v.pol
        w = nv.get((v.wavelength_nm, v.theta_deg, v.pol, v.quantity))
        cells = ("-", "-", "-", "-") if w is None else (
            _cell(w), f"{v.limit.value - w.limit.value:+.4f}", f"{w.values[-1]:.4f}", f"{w.seconds[-1]:.1f}")
        lines.append(f"| {v.wavelength_nm:g} | {v.theta_deg:g} | {pol} | {v.quantity} | {_cell(v)} | {cells[0]} "
                     f"| {cells[1]} | {v.values[-1]:.4f} / {cells[2]} | {v.seconds[-1]:.1f} / {cells[3]} |")
    lines += ["", "| nm | pol | side | forward | backward | difference | within the bars | difference at 35 |",
              "|---|---|---|---|---|---|---|---|"]
    for c in g2.reciprocity(cache, orders=g2.ASR_ORDERS, rules=(g2.ASR_RULE,)):
        lines.append(f"| {c.wavelength_nm:g} | {c.pol} | {c.side} | {c.forward.value:.5f} ± {c.forward.error:.5f} "
                     f"| {c.backward.value:.5f} ± {c.backward.error:.5f} | {c.difference:.5f} | "
                     f"{'yes' if c.within_errors else 'no'} | {abs(c.forward.last_value - c.backward.last_value):.5f} |")
    return "\n".join(lines)


def both_asr_tables(cache: SolveCache) -> list[g2.ConvergedValue]:
    """Li's rule in stretched coordinates everywhere and the NV rule's where published."""
    return g2.asr_table(cache) + g2.asr_table(cache, rule=g2.ASR_NV_RULE, only=g2.ASR_NV_DIRECTIONS)


def published_literal(cache: SolveCache, table: Callable = g2.converged_table) -> str:
    """The converged values as the Python dict tests/rcwa/test_gold2d_convergence.py holds them to."""
    rows = [f"    ({v.wavelength_nm!r}, {v.theta_deg!r}, {v.pol!r}, {v.quantity!r}, {v.rule!r}): "
            f"({v.limit.value:.6f}, {v.limit.error:.6f})," for v in table(cache)]
    return "PUBLISHED = {\n" + "\n".join(rows) + "\n}"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-orders", type=int, default=CurveConfig.max_orders, help="gold2d curve's highest N")
    parser.add_argument("--gold2d-table", action="store_true", help="print the converged-value table (markdown)")
    parser.add_argument("--solve-cache", default=None, help="the raw-solve cache (JSON)")
    parser.add_argument("--published-literal", action="store_true",
                        help="print the converged values as the heavy test's PUBLISHED dict")
    parser.add_argument("--asr-table", action="store_true",
                        help="print adaptive spatial resolution's converged values and reciprocity (about 20 minutes cold)")
    parser.add_argument("--asr-literal", action="store_true", help="print them as the heavy test's PUBLISHED_ASR dict")
    args = parser.parse_args(argv)
    cache = g2.open_cache(args.solve_cache)
    if args.gold2d_table or args.published_literal:
        print(gold2d_markdown(cache) if args.gold2d_table else published_literal(cache))
        return
    if args.asr_table or args.asr_literal:
        print(asr_markdown(cache) if args.asr_table else published_literal(cache, both_asr_tables).replace(
            "PUBLISHED =", "PUBLISHED_ASR ="))
        return
    points = lamellar_tm_study()
    _print(points, "Metallic lamellar grating, TM, Littrow order (reference: Li rule, 801 harmonics)")
    for target in (1e-2, 1e-3):
        li, laurent = orders_to_reach(points, "li", target), orders_to_reach(points, "laurent", target)
        print(f"harmonics to reach {target:g}: inverse rule {li}, Laurent rule {laurent or '> ' + str(LAMELLAR_ORDERS[-1])}")
    print()
    _print(gold2d_study(), "gold2d: zero-order transmission, 550 nm, normal incidence, x-polarized (s at phi = 0)")
    _print_curve(cache, args.max_orders)


if __name__ == "__main__":
    main()
