// Eigenmodes of one layer of a periodic stack.
//
// Normalization (all lengths times k0, H replaced by h = Z0 H): inside a layer the
// tangential fields psi = [Ex; Ey] and phi = [hx; hy] of the retained harmonics obey
//     d psi / dz = i P phi,   d phi / dz = i Q psi,
// with (Kx, Ky diagonal; Z = [[eps]]^{-1}, the inverse of the Laurent matrix)
//     P = [[Kx Z Ky, I - Kx Z Kx], [Ky Z Ky - I, -Ky Z Kx]]
//     Q = [[-Kx Ky - Eyx, Kx^2 - Eyy], [Exx - Ky^2, Ky Kx + Exy]],
// the PQ form of [Liu 2012, Eqs. 7-10] (S4) written
// for an anisotropic effective permittivity [Exx Exy; Eyx Eyy] so that every Fourier
// factorization rule (Laurent, [Li 1996] / [Li 1997], normal vector method) enters only
// through it.
// A mode is psi = W e^{-+ i kz z}, phi = -+ V e^{-+ i kz z} with P Q W = W diag(kz^2) and
// V = Q W diag(kz)^{-1}; the upper sign is the down-going wave (toward -z).
#pragma once

#include <memory>
#include <optional>

#include "linalg.hpp"

namespace rcwa {

// Normalized tangential wave numbers (kx, ky) / k0 of the N retained harmonics.
struct Harmonics {
    std::vector<double> kx;
    std::vector<double> ky;
    int size() const { return static_cast<int>(kx.size()); }
};

// Longitudinal wave numbers closer to zero than this are moved to this magnitude inside
// finite layers, where kz = 0 makes the up- and down-going modes coincide (see
// regularize_kz). Outside, in the superstrate and substrate, kz = 0 is handled exactly.
constexpr double kKzFloor = 1e-8;

// sqrt with Im >= 0 (Re >= 0 when Im == 0), exact for purely real arguments: the
// outgoing branch of workbench/core/conventions.py (kz_branch), which it must equal. The
// half-spaces' kz are taken here only (stack.cpp, half_space_kz), never in Python;
// tests/rcwa/test_core_boundary.py checks both agree on lossy, lossless, grazing and
// -0.0j arguments.
cplx outgoing_sqrt(cplx kz2);
cplx regularize_kz(cplx kz);
// kz of a mode of a finite layer from its eigenvalue kz^2 (see modes.cpp).
cplx layer_kz(cplx kz2);

class LayerModes {
  public:
    virtual ~LayerModes() = default;
    virtual Mat apply_W(const Mat& B) const = 0;
    virtual Mat apply_V(const Mat& B) const = 0;
    virtual Mat apply_W_inverse(const Mat& B) const = 0;
    virtual Mat apply_V_inverse(const Mat& B) const = 0;
    // The 2N x 2N matrices themselves. The defaults apply the operators to the identity;
    // layers whose blocks are at hand assemble them in O(N^2) instead.
    virtual Mat W() const { return apply_W(identity()); }
    virtual Mat V() const { return apply_V(identity()); }
    virtual Mat W_inverse() const { return apply_W_inverse(identity()); }
    virtual Mat V_inverse() const { return apply_V_inverse(identity()); }
    const CVec& kz() const { return kz_; }
    // Whether a one-layer stack of this layer is solved directly (stack.cpp, solve_direct)
    // rather than through W^-1 and V^-1: dense W and V at hand (DenseModes), or a lamellar
    // layer whose inverses were not computed (LamellarParts::inverses).
    virtual bool dense() const { return false; }
    // W and V themselves where the layer stores them (DenseModes), without a copy; nullptr
    // where they would have to be assembled (call W(), V() then).
    virtual const Mat* stored_W() const { return nullptr; }
    virtual const Mat* stored_V() const { return nullptr; }

  protected:
    Mat identity() const { return Mat::identity(static_cast<int>(kz_.size())); }
    CVec kz_;
};

// A homogeneous layer: no eigen-solve. W = I and V = Q / kz, block-diagonal per order.
std::unique_ptr<LayerModes> uniform_modes(const Harmonics& h, cplx eps);

// A 1D lamellar layer (harmonics along x only, ky the same for all). E is the Laurent
// matrix [[eps]], Exx the matrix used for Dx (Li's inverse rule [[1/eps]]^{-1}, or [[eps]]
// for the Laurent rule). Two N x N eigen-solves, independent of ky (see lamellar.cpp).
struct LamellarEigen {
    std::vector<double> kx;
    Mat WA;        // eigenvectors of MA = E - Kx^2 (TE-like family, pure Ey)
    CVec muA;      // its eigenvalues
    Mat VB;        // eigenvectors of MB = Exx (I - Kx Z Kx) (TM-like family, pure hy)
    CVec muB;
    Mat B_VB;      // (I - Kx Z Kx) VB
    Mat ZKx_VB;    // Z Kx VB
    // For the block inverses of W and V (lamellar.cpp), all independent of ky:
    Mat WA_inv, VB_inv, B_VB_inv;
    Mat M1;        // WA^-1 Z Kx VB (B VB)^-1
    Mat M3;        // VB^-1 Kx WA muA^-1 WA^-1
    int refined = 0;    // how many of the two eigen-solves were refined from `near` (0-2)
    int hermitian = 0;  // how many were solved as Hermitian problems (0-2; see LamellarParts)
    int real = 0;       // of those, how many in real arithmetic (real_by_phase)
    int inverse_iteration = 0;  // how many general ones were solved by eig_small (linalg.hpp)
    int complex_symmetric = 0;  // how many general ones were solved as complex symmetric (complex_symmetric.hpp)
    bool inverses = true;       // WA_inv, VB_inv, B_VB_inv, M1, M3 computed (LamellarParts::inverses)
};
// Which parts of a LamellarEigen to compute. At ky = 0 the families never couple: the TE
// family (A) alone serves s incidence, the TM family (B) alone p incidence, and the
// coupling blocks M1, M3 (multiplied by ky) are not needed (polarized.hpp). Parts left
// out stay empty.
struct LamellarParts {
    bool te = true;       // WA, muA, WA_inv
    bool tm = true;       // VB, muB, B_VB, VB_inv, B_VB_inv
    bool conical = true;  // ZKx_VB; M1, M3 (need both families)
    // Lossless layers (E and Exx Hermitian to kHermitianTolerance: a real permittivity
    // everywhere, and kx real) may use Hermitian eigen-solvers, whose eigenvectors also give
    // the inverses: TE, MA = E - Kx^2 is Hermitian (zheevd: WA unitary, WA^-1 = WA^H); TM,
    // MB v = mu v is the Hermitian-definite pencil (Exx B Exx) w = mu Exx w with v = Exx w
    // (zhegvd, when Exx is positive definite: every permittivity > 0), so VB^-1 = W^H and
    // B VB = W mu. Otherwise, or with a `near` guess, the general zgeev path, or below
    // kInverseIterationMax harmonics eig_small (linalg.hpp) where this flag is set.
    bool hermitian = false;
    // The inverses' blocks WA_inv, VB_inv, B_VB_inv, M1, M3, which only the ETM stack uses.
    // Without them the layer's modes can only be solved directly (stack.cpp, solve_direct:
    // a one-layer stack in a single solve), and LayerModes::dense says so.
    bool inverses = true;
    // Lossy (or not Hermitian-definite) layers whose matrices D E D^H, D Exx D^H, D Z D^H are
    // complex symmetric for some diagonal unitary D (symmetric_by_phase: a profile symmetric
    // about a point) are solved by eig_complex_symmetric (TE) and through Exx' = G G^T (TM),
    // before `near`'s refinement and eig_small / zgeev, which remain for what it declines.
    bool complex_symmetric = false;
};
constexpr double kHermitianTolerance = 1e-14;
// |Im| of D A D^H (real_by_phase) below which a lossless layer is solved in real arithmetic,
// relative to A's largest entry: round-off of the Fourier coefficients and of Z = E^-1.
constexpr double kRealTolerance = 1e-13;
// Asymmetry |A - A^T| (relative to the largest entry) below which a lossy layer's phase-moved
// E, Exx, Z are treated as complex symmetric (symmetric_by_phase); each use is then checked
// on its residual (complex_symmetric.hpp), so this only decides where to try.
constexpr double kSymmetricTolerance = 1e-11;
// The complex-symmetric path runs below this many harmonics, where the path it replaces
// (eig_small) is itself not zgeev: issue 17 allows no fast path to move a result by more
// than 1e-12, and at 121 harmonics it moved the CD's p amplitudes by 1.6e-12 from zgeev's
// (efficiencies 6e-13), against 1e-14 today; below it, it is closer to zgeev than
// eig_small (at 61: 1.6e-12 against 1e-11 on the worst point of 400-700 nm x 0-80 deg).
constexpr int kComplexSymmetricMax = kInverseIterationMax;
// Z = E^-1 is passed in (it depends on the wavelength only; unused when only the TE
// family is asked for). `near`: the solution at a nearby kx, whose eigenvectors seed
// eig_from_guess (linalg.hpp) instead of a full eigen-solve; nullptr, or a guess that does
// not converge, means a full solve. `inv_eps`: [[1/eps]] of Li's rule, given with an empty
// Exx so that Exx = [[1/eps]]^-1 is formed only where a path needs it (the complex-symmetric
// TM path does not).
LamellarEigen lamellar_eigen(const std::vector<double>& kx, const Mat& E, const Mat& Exx, const Mat& Z,
                             const LamellarEigen* near = nullptr, const LamellarParts& parts = {},
                             const Mat* inv_eps = nullptr);
std::unique_ptr<LayerModes> lamellar_modes(const std::vector<double>& kx, const LamellarEigen& eig,
                                           double ky);

// Q of the header comment (2N x 2N) for a general layer (general_modes needs no P:
// pq_product).
Mat q_matrix(const Harmonics& h, const Mat& Exx, const Mat& Exy, const Mat& Eyx, const Mat& Eyy);
// P and Q of the header comment (2N x 2N) for a general layer; Z = [[eps]]^-1 is given
// (it depends on the wavelength only, so a sweep takes it once: sweep.cpp).
void pq_matrices(const Harmonics& h, const Mat& Z, const Mat& Exx, const Mat& Exy, const Mat& Eyx, const Mat& Eyy,
                 Mat& P, Mat& Q);
// P Q from Z and Q, using P's structure (a rank-N product plus a block permutation): a
// quarter of the products of the 2N x 2N matmul(P, Q); equal to it to round-off.
Mat pq_product(const Harmonics& h, const Mat& Z, const Mat& Q);

// A general (2D, or anisotropic) layer: one 2N x 2N eigen-solve of P Q (Z as above).
std::unique_ptr<LayerModes> general_modes(const Harmonics& h, const Mat& Z, const Mat& Exx,
                                          const Mat& Exy, const Mat& Eyx, const Mat& Eyy);

// Dense modes (W, V given), with LU factorizations for the inverses, taken on first use
// (a one-layer stack solved directly needs none). One object serves one thread.
class DenseModes : public LayerModes {
  public:
    DenseModes(Mat W, Mat V, CVec kz);
    Mat apply_W(const Mat& B) const override { return matmul(W_, B); }
    Mat apply_V(const Mat& B) const override { return matmul(V_, B); }
    Mat apply_W_inverse(const Mat& B) const override { return lu(luW_, W_).solve(B); }
    Mat apply_V_inverse(const Mat& B) const override { return lu(luV_, V_).solve(B); }
    Mat W_inverse() const override { return lu(luW_, W_).inverse(); }
    Mat V_inverse() const override { return lu(luV_, V_).inverse(); }
    Mat W() const override { return W_; }
    Mat V() const override { return V_; }
    bool dense() const override { return true; }
    const Mat* stored_W() const override { return &W_; }
    const Mat* stored_V() const override { return &V_; }

  private:
    static const LU& lu(std::optional<LU>& slot, const Mat& A) {
        if (!slot) slot.emplace(A);
        return *slot;
    }
    Mat W_, V_;
    mutable std::optional<LU> luW_, luV_;
};

}  // namespace rcwa
