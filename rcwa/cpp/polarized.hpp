// One polarization through a 1D stack in classical mount (every ky = 0): TE and TM
// decouple in every layer and at both half-spaces, so each is an N-size problem.
//
// With ky = 0 the s direction of every harmonic is +-y (sigma_i = sign(kx_i), or the
// given s-hat where kx_i = 0) and p is +-x: the s (TE) field is (Ey, hx), the p (TM) field
// (Ex, hy) ([Moharam 1995a, Sec. 2] (TE) and [Moharam 1995a, Sec. 3] (TM); [Li 1996,
// Eq. 37] for the TM matrix). A layer's modes for one
// polarization are u = W c, v = V c (u the E component, v the h component above), the
// blocks of the 2N x 2N W and V of modes.hpp that couple that polarization's components
// to its family of modes: the other blocks are zero at ky = 0. The enhanced
// transmittance matrix of stack.cpp then runs unchanged on N x N blocks: its O(n^3)
// kernels cost a quarter per polarization, and a request for one polarization needs one
// eigen-solve per layer instead of two.
#pragma once

#include "stack.hpp"

namespace rcwa {

enum class Polarization { TE, TM };  // s and p incidence

// An N x N operator that is either dense or diagonal (a uniform layer's).
struct Operator {
    Mat dense;        // used when `diag` is empty
    CVec diag;
    Mat apply(const Mat& B) const;          // this B
    Mat times_diagonal(const CVec& d) const;  // this diag(d)
    Mat matrix() const;
};

struct PolarizedModes {
    Operator W, V, W_inverse, V_inverse;
    CVec kz;
};

PolarizedModes uniform_polarized(const std::vector<double>& kx, cplx eps, Polarization pol);
// From a LamellarEigen holding the family of `pol` (modes.hpp, LamellarParts).
PolarizedModes lamellar_polarized(const LamellarEigen& eig, Polarization pol);

// Whether the problem decouples: ETM stack, every ky exactly 0, and where a harmonic has
// kt = 0 the given s-hat is +-y (s_x = 0), and at least one layer (`thickness`). The
// layers must then be uniform or lamellar (the caller checks).
bool decouples(const StackProblem& problem, StackMethod method);

// The solution for incidence `pol` into column 0 (TE) or 1 (TM) of out.r and out.t, which
// must be 2N x 2 with out.kz_* filled (half_space_kz). `problem` gives the harmonics,
// media, s direction and thicknesses; its `layers` are not read.
void solve_polarized(const StackProblem& problem, Polarization pol, const std::vector<PolarizedModes>& layers,
                     StackSolution& out);

// The same for a stack of exactly one layer whose W and V are given (its inverses need not
// be: LamellarParts::inverses false): the layer's boundary conditions with both half-spaces
// as one 2N x 2N system (solve_polarized_direct in polarized.cpp), the N-size counterpart of
// stack.cpp's solve_direct. Equal to solve_polarized to round-off.
void solve_polarized_direct(const StackProblem& problem, Polarization pol, const PolarizedModes& layer,
                            StackSolution& out);

}  // namespace rcwa
