// Eigen-decomposition of complex symmetric matrices (A^T = A, not Hermitian) through a
// complex-symmetric tridiagonal form: the lossy 1D layers that are symmetric about a point
// (issue 17, `complex_symmetric` fast path). The transformations are complex orthogonal
// (Q^T Q = I), not unitary, so nothing bounds their error a priori: every step checks its
// growth and the result is refined and accepted only on an a-posteriori residual; callers
// fall back to eig_small / eig otherwise.
#pragma once

#include <functional>
#include <optional>
#include <vector>

#include "linalg.hpp"

namespace rcwa {

// Relative residual ||A W - W diag(w)||_F <= tolerance ||A||_F ||W||_F an accepted
// decomposition meets (zgeev's are ~5e-16, eig_small's ~1e-14).
constexpr double kComplexSymmetricTolerance = 1e-13;
// Largest growth a complex-orthogonal reflector or rotation may have (|v|^2 / |v^T v|,
// (|f|^2 + |g|^2) / |f^2 + g^2|), and a symmetric factor (max |G|^2 / max |A|).
constexpr double kComplexSymmetricGrowth = 1e6;

// Eigen-decomposition of a complex symmetric matrix (the lower triangle is reduced; the
// whole of A is used for the refinement and the residual check): reflectors
// H = I - 2 v v^T / (v^T v) (complex orthogonal, H^T H = I) reduce A to a complex symmetric
// tridiagonal T = Q^T A Q [Bar-On 1997]; T's eigenvalues by the implicit QL
// algorithm (EISPACK's imtql1: [Martin 1968]) in complex arithmetic, its rotations
// c^2 + s^2 = 1 complex (as [Cullum 1985], CMTQL1); its eigenvectors by
// inverse iteration on T (two steps; close eigenvalues' vectors orthogonalized in the
// bilinear form), W = Q Y. Such reductions lose accuracy where the reflectors and rotations
// grow ([Schabauer 2010] measured it against
// zggev); here one step of first-order refinement against A itself (refinement_step, with
// L = W: a symmetric matrix's left eigenvectors are its right ones transposed) restores
// residuals of ~1e-16 relative on the CD's matrices (zgeev's: ~5e-16). Columns of unit
// 2-norm, as zgeev's. Nothing on a breakdown (growth above kComplexSymmetricGrowth, no
// convergence, a close pair the refinement cannot separate) or a probed residual above
// `tolerance` (probed_residual_ok). refine = false: the eigenvalues from QL and the vectors
// from inverse iteration (bilinear-normalized), unrefined and unchecked, for a caller that
// refines them against the matrix it needs (lamellar.cpp's TM pencil).
std::optional<Eigen> eig_complex_symmetric(Mat A, double tolerance = kComplexSymmetricTolerance, bool refine = true);

// The refinement step above for M V = V diag(w) with left eigenvectors L (L^T M = diag(w)
// L^T in exact arithmetic; L = V for a symmetric M), given M V: K = L^T M V, S = L^T V,
// w_j = K_jj / S_jj (in `values`), and I + P, P_ij = (K_ij - w_j S_ij) / ((w_j - w_i) S_ii)
// for i != j, the first-order correction V <- V (I + P) ([Stewart 1990,
// Sec. V.2], in the two-sided form). Nothing where a correction exceeds
// 1e-2 (a close pair).
std::optional<Mat> refinement_step(const Mat& L, const Mat& V, const Mat& MV, CVec& values);
// The same from [K S] (n x 2n) given, as for a pencil M v = w N v with M, N symmetric:
// K = V^T M V, S = V^T N V.
std::optional<Mat> refinement_from(const Mat& KS, CVec& values);
// A x.
CVec matvec(const Mat& A, const CVec& x);
// Scales V's columns to unit 2-norm, and the same columns of the matrices `alongside`.
void unit_columns(Mat& V, std::vector<Mat*> alongside = {});
// The a-posteriori check ||M V x - N V diag(w) x|| <= absolute + relative ||M V x|| for two
// random-sign vectors x (E ||R x||^2 = ||R||_F^2 for R = M V - N V diag(w)): O(n^2) instead
// of another product of n x n matrices. N: the identity where not given (a pencil's B).
bool probed_residual_ok(const std::function<CVec(const CVec&)>& apply_M, const Mat& V, const CVec& values,
                        double absolute, double relative, const std::function<CVec(const CVec&)>& apply_N = {});

// Whether A equals its transpose to `tolerance` relative to its largest entry.
bool is_complex_symmetric(const Mat& A, double tolerance);

// A diagonal unitary D = diag(d) that makes the Toeplitz-like matrices `As` complex
// symmetric together, D A D^H = (D A D^H)^T to `tolerance`: with harmonics m = -M..M (row
// i has m_i = i - M), a profile even about x0 has A_ij = c(m_i - m_j), c(g) = r(g)
// exp(-i g theta) with r even (theta = g0 x0), and d_i = u^(m_i), u = exp(i theta) =
// sqrt(A_01 / A_10) moves the origin to x0 (compare real_by_phase). Empty d: the matrices
// are symmetric as they are (the profile is even about 0 or about half the period, as the
// CD). Nothing when there is no such D.
std::optional<CVec> symmetric_by_phase(const std::vector<const Mat*>& As, double tolerance);
// D A D^H for D = diag(d); A itself for an empty d.
Mat moved_by_phase(const Mat& A, const CVec& d);

// A = G G^T with G lower triangular (G = L diag(sqrt(D)) of A = L D L^T, no pivoting; the
// lower triangle of A is read). Nothing when a pivot vanishes or max |G|^2 exceeds
// kComplexSymmetricGrowth max |A|.
std::optional<Mat> symmetric_factor(Mat A);
// op(G) B or op(G)^-1 B for a lower-triangular G (side 'L') or B op(G) (side 'R'); op is 'N' or 'T'.
void triangular_multiply(const Mat& G, Mat& B, char side, char trans);
void triangular_solve(const Mat& G, Mat& B, char side, char trans);

}  // namespace rcwa
