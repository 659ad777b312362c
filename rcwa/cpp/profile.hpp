// Convolution (Toeplitz) matrices of a 1D piecewise-constant profile, the Fourier input of
// a lamellar layer, built in the core so that a 1D solve's Python does no array work.
#pragma once

#include <vector>

#include "sweep.hpp"

namespace rcwa {

// One piece of a profile on [0, period): value on [x0, x1).
struct ProfileSegment {
    double x0 = 0.0, x1 = 0.0;
    cplx value;
};

// C[i, j] = c(m_j - m_i) for the harmonics m_i = i - M (i = 0..2M, `harmonics` = 2M + 1),
// with c(g) = (1 / period) sum_s f(value_s) int_{x0_s}^{x1_s} exp(-i q x) dx, q = 2 pi g /
// period, each integral in closed form, (x1 - x0) sinc(q (x1 - x0) / 2) exp(-i q (x0 + x1) / 2)
// (workbench.core.conventions' order sign: [Li 1996, Eq. 3] with the sign
// of rcwa/fourier.py; the same sums as rcwa.fourier.profile_coefficients). f is the
// identity, or 1 / value with `reciprocal` ([[1/eps]] of Li's inverse rule).
Mat profile_toeplitz(const std::vector<ProfileSegment>& segments, double period, int harmonics, bool reciprocal);

// A lamellar layer (make_layer, checked) of the profile: E = [[eps]] and, by Li's inverse
// rule (`inverse_rule`), [[1/eps]] (LayerInput::inverse_rule), else Exx = E (Laurent).
LayerInput lamellar_layer(double k0_thickness, double period, const std::vector<ProfileSegment>& segments,
                          int harmonics, bool inverse_rule);

}  // namespace rcwa
