// Mirror-symmetry sectors of a 2D problem: the stack solved in the even/odd combinations
// of each harmonic and its mirror image, one sector at a time, and only the sectors the
// incident wave excites.
//
// The reduction is the group-theoretic one of [Bai 2005a] (the C2 case; the C4 case in
// [Bai 2005b]): the
// problem is split into symmetry modes of the grating's group, each solved with the
// unknowns its symmetry leaves, and the solutions superposed. Here the group is that of
// the cell's mirrors ({e, sigma_x}, {e, sigma_y} or C2v = {e, sigma_x, sigma_y, C2}),
// written for the PQ form of modes.hpp and the enhanced transmittance stack. The
// derivation:
//
// A mirror sigma: x -> 2c - x of every layer (the same c for all) maps a solution of
// Maxwell's equations to another: E'(r) = M E(sigma r), h'(r) = -M h(sigma r) (E is a
// polar vector, h = Z0 H an axial one), M = diag(-1, 1, 1). Where the harmonics' set is
// mapped onto itself (kx0 = 0: kx of the image of harmonic i is -kx_i), a field
// f(x) = sum_i f_i exp(i k0 kx_i x) maps to (S f)_{i'} = p_i f_i with i' the image of
// i and p_i = exp(2 i k0 kx_i c). On the tangential fields psi = [Ex; Ey] and
// phi = [hx; hy] this is S_E = diag(-S, S) and S_H = diag(S, -S) (y -> 2c - y: S_E =
// diag(S, -S), S_H = diag(-S, S)), and the layer's operators intertwine them:
// S_E P = P S_H and S_H Q = Q S_E, since [[eps]], Exx and Eyy commute with the scalar S
// and Exy, Eyx anticommute (checked on the matrices here, to kSymmetryTolerance). So
// S_E commutes with PQ, and S_E, S_H, S_A (the action on the s and p amplitudes of the
// half-spaces' plane waves: an s wave maps to +-an s wave of the image order, a p wave
// to -+ a p wave, the sign sigma_i = s_{i'} . M s_i) commute with every step of the
// stack. With one or two commuting mirrors (group G of order 2 or 4, characters
// chi(g) = +-1) the projectors P_chi = |G|^-1 sum_g chi(g) S_g split each of the three
// 2N spaces into |G| orthogonal sectors; the sector basis is P_chi e_j, normalized, for
// one j per orbit of G (sparse: at most four nonzeros a column). In a sector of size n
// the layer's problem is P_s Q_s = U_E^H P Q U_E (n x n, about 2N / |G|), the
// half-spaces' waves are U_E^H F D and U_H^H G D, the closure's rows D^H project_up,
// and the incident wave excites a sector only where D^H has a nonzero at its row: at
// normal incidence with s-hat = y, s (Ey) lies in the sector even in x and odd in y, p
// (Ex) in the one odd in x and even in y. The solution is the sum of the sectors'.
// Eigen-solves cost (2N / |G|)^3 each: a quarter (one mirror, both sectors) or an
// eighth (two mirrors, two of four sectors, unpolarized) of the full one.
//
// At normal incidence the sectors use s-hat = y for the specular order (every mirror maps
// it to +-itself), whatever the caller's; r is measured and t converted in the caller's.
// Where the problem does not respect a mirror (kx0 != 0 for x -> -x, ky0 != 0 for
// y -> -y, to 1e-14; matrices that do not commute with it, such as the normal-vector
// rule's for shapes off the origin, whose sampled normal field is symmetric to ~5e-11
// only), that mirror is dropped; with none left the general path runs.
#pragma once

#include <optional>

#include "sweep.hpp"

namespace rcwa {

// Relative tolerance of the layer matrices' commutation with a mirror (exact Fourier
// coefficients of a symmetric cell commute to ~1e-15; a shape 1e-9 um off its mirror
// image breaks it by ~1e-9).
constexpr double kSymmetryTolerance = 1e-11;

// The mirrors of problem.mirrors that every layer respects: uniform layers, and general
// ones whose matrices commute with the mirror (above). Checked once per problem.
std::vector<Mirror> respected_mirrors(const SweepProblem& problem);
// Those of them that one point (its harmonics) respects too, checked first (O(N) each, the
// layers' O(N^2)): a single solve off every mirror plane then takes neither the layers'
// check nor [[eps]]^-1 block by block (laurent_inverse), which only solve_sectors uses.
std::vector<Mirror> respected_mirrors(const SweepProblem& problem, const StackProblem& point);

// Z = E^-1 for the Laurent matrix E of a layer that commutes with every scalar mirror
// action of `mirrors` (from respected_mirrors; for scalar fields, whatever the incidence):
// E is block-diagonal in their sectors, so Z is taken block by block (a sixteenth of the
// work with two mirrors). Without mirrors, an LU inverse.
Mat laurent_inverse(const Mat& E, const std::vector<Mirror>& mirrors);

// One point (`point`: its harmonics, media, s-hat and thicknesses; its layers are not
// read) of `problem` (its layers' inputs) solved sector by sector in the `mirrors` (from
// respected_mirrors) this point respects, or nothing where none applies (see above) or
// the stack is not the ETM. Columns of r and t that `incidence` does not ask for are NaN.
// Z: each general layer's laurent_inverse (others empty).
std::optional<StackSolution> solve_sectors(const SweepProblem& problem, const StackProblem& point,
                                           const std::vector<Mirror>& mirrors, Incidence incidence,
                                           const std::vector<Mat>& Z);

}  // namespace rcwa
