#include "efficiency.hpp"

#include <stdexcept>
#include <string>

namespace rcwa {

namespace {

// r(p, row, c), t(p, row, c): amplitude of row `row` (s rows 0..K-1, p rows K..2K-1) for
// incidence c at point p; kz1(p, i), kz2(p, i): the half-spaces' kz of harmonic i.
template <class R, class T, class Kz1, class Kz2>
Efficiencies compute(std::size_t points, std::size_t kept, std::size_t zero, cplx eps1, cplx eps2, const R& r, const T& t,
                     const Kz1& kz1, const Kz2& kz2) {
    if (zero >= kept) throw std::invalid_argument("efficiencies: zero " + std::to_string(zero) + " outside the harmonics");
    Efficiencies out;
    out.points = points;
    out.kept = kept;
    out.R.resize(points * kept * 2);
    out.T.resize(points * kept * 2);
    out.into.resize(points * kept * 2);
    const bool lossless_substrate = eps2.imag() == 0.0 && eps2.real() > 0.0;
    for (std::size_t p = 0; p < points; ++p) {
        const cplx kz0 = kz1(p, zero);
        const double power_in[2] = {kz0.real(), (kz0 / eps1).real()};
        for (std::size_t i = 0; i < kept; ++i) {
            const double up_s = kz1(p, i).real(), up_p = (kz1(p, i) / eps1).real();
            const double down_s = kz2(p, i).real(), down_p = (kz2(p, i) / eps2).real();
            for (std::size_t c = 0; c < 2; ++c) {
                const std::size_t at = (p * kept + i) * 2 + c;
                out.R[at] = (std::norm(r(p, i, c)) * up_s + std::norm(r(p, kept + i, c)) * up_p) / power_in[c];
                out.into[at] = (std::norm(t(p, i, c)) * down_s + std::norm(t(p, kept + i, c)) * down_p) / power_in[c];
                out.T[at] = lossless_substrate ? out.into[at] : 0.0;
            }
        }
    }
    return out;
}

}  // namespace

Efficiencies efficiencies(const StackSolution& s, int zero, cplx eps1, cplx eps2) {
    const std::size_t n = s.kz_superstrate.size();
    if (zero < 0) throw std::invalid_argument("efficiencies: negative zero order");
    return compute(
        1, n, static_cast<std::size_t>(zero), eps1, eps2,
        [&](std::size_t, std::size_t row, std::size_t c) { return s.r(static_cast<int>(row), static_cast<int>(c)); },
        [&](std::size_t, std::size_t row, std::size_t c) { return s.t(static_cast<int>(row), static_cast<int>(c)); },
        [&](std::size_t, std::size_t i) { return s.kz_superstrate[i]; },
        [&](std::size_t, std::size_t i) { return s.kz_substrate[i]; });
}

Efficiencies efficiencies(const SweepResult& s, int zero, cplx eps1, cplx eps2) {
    const std::size_t k = s.kept;
    if (zero < 0) throw std::invalid_argument("efficiencies: negative zero order");
    return compute(
        s.points, k, static_cast<std::size_t>(zero), eps1, eps2,
        [&](std::size_t p, std::size_t row, std::size_t c) { return s.r[(p * 2 * k + row) * 2 + c]; },
        [&](std::size_t p, std::size_t row, std::size_t c) { return s.t[(p * 2 * k + row) * 2 + c]; },
        [&](std::size_t p, std::size_t i) { return s.kz_superstrate[p * k + i]; },
        [&](std::size_t p, std::size_t i) { return s.kz_substrate[p * k + i]; });
}

}  // namespace rcwa
