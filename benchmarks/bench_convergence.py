"""The order-convergence curves of rcwa.convergence, printed (``make bench``)."""

from __future__ import annotations

from rcwa.convergence import LAMELLAR_ORDERS, ConvergencePoint, gold2d_study, lamellar_tm_study, orders_to_reach


def _print(points: list[ConvergencePoint], title: str) -> None:
    print(title)
    print(f"{'rule':>8} {'orders':>7} {'value':>12} {'error':>10} {'seconds':>8}")
    for p in points:
        error = f"{p.error:10.2e}" if p.error is not None else f"{'-':>10}"
        print(f"{p.rule:>8} {p.orders:>7} {p.value:12.6f} {error} {p.seconds:8.3f}")
    print()


def main() -> None:
    points = lamellar_tm_study()
    _print(points, "Metallic lamellar grating, TM, Littrow order (reference: Li rule, 801 harmonics)")
    for target in (1e-2, 1e-3):
        li, laurent = orders_to_reach(points, "li", target), orders_to_reach(points, "laurent", target)
        print(f"harmonics to reach {target:g}: inverse rule {li}, Laurent rule {laurent or '> ' + str(LAMELLAR_ORDERS[-1])}")
    print()
    _print(gold2d_study(), "gold2d: zero-order transmission, 550 nm, normal incidence, x-polarized (s at phi = 0)")


if __name__ == "__main__":
    main()
