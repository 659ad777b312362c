#include "profile.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace rcwa {

Mat profile_toeplitz(const std::vector<ProfileSegment>& segments, double period, int harmonics, bool reciprocal) {
    if (harmonics < 1 || harmonics % 2 == 0)
        throw std::invalid_argument("profile_toeplitz: harmonics must be odd and >= 1, got " + std::to_string(harmonics));
    if (!(period > 0.0) || !std::isfinite(period))
        throw std::invalid_argument("profile_toeplitz: period must be finite and > 0");
    const int reach = harmonics - 1;  // g = m_j - m_i in [-2M, 2M]
    const double pi = std::acos(-1.0);
    CVec c(2 * static_cast<std::size_t>(reach) + 1);  // c[g + reach]
    for (const ProfileSegment& s : segments) {
        if (!(s.x1 > s.x0)) throw std::invalid_argument("profile_toeplitz: a segment must have x1 > x0");
        const cplx v = reciprocal ? 1.0 / s.value : s.value;
        const double width = s.x1 - s.x0, centre = 0.5 * (s.x0 + s.x1);
        c[reach] += v * width;
        for (int g = 1; g <= reach; ++g) {
            // c(g) and c(-g) share the envelope and conjugate phases.
            const double q = 2.0 * pi * g / period, half = 0.5 * q * width;
            const double envelope = width * std::sin(half) / half;
            const double cs = std::cos(q * centre), sn = std::sin(q * centre);
            c[reach + g] += v * cplx(envelope * cs, -envelope * sn);
            c[reach - g] += v * cplx(envelope * cs, envelope * sn);
        }
    }
    Mat C(harmonics, harmonics);
    for (int j = 0; j < harmonics; ++j)
        for (int i = 0; i < harmonics; ++i) C(i, j) = c[static_cast<std::size_t>(j - i + reach)] / period;
    return C;
}

LayerInput lamellar_layer(double k0_thickness, double period, const std::vector<ProfileSegment>& segments,
                          int harmonics, bool inverse_rule) {
    Mat E = profile_toeplitz(segments, period, harmonics, false);
    Mat second = inverse_rule ? profile_toeplitz(segments, period, harmonics, true) : E;
    return make_layer(LayerKind::Lamellar, k0_thickness, 0.0, {std::move(E), std::move(second)}, inverse_rule);
}

}  // namespace rcwa
