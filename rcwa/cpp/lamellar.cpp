// Modes of a 1D lamellar layer in conical incidence from two N x N eigen-solves.
//
// With Ky = ky I (one ky for every harmonic) and Z = E^{-1}, the matrix P Q of modes.hpp
// is block lower-triangular,
//     P Q = [[MB' - ky^2, 0], [., MA - ky^2]],   MA = E - Kx^2,
// and Q P = [[MA - ky^2, 0], [., MB - ky^2]],   MB = Exx (I - Kx Z Kx),
// (MB' = (I - Kx Z Kx) Exx is similar to MB). So one family of modes has Ex = 0 (pure Ey,
// eigenvectors WA of MA: TE-like) and the other has hx = 0 (pure hy, eigenvectors VB of
// MB: TM-like); kz^2 = mu - ky^2 for both. This is the decoupling of
// [Moharam 1995a, Eqs. 40-49] (conical diffraction) written for Li's inverse rule
// ([Li 1996, Eq. 37]: Exx = [[1/eps]]^{-1}). The
// eigenvectors do not depend on ky; only kz and the assembly below do.
//   family A:  psi = [0; WA],                      phi = [-WA muA; ky Kx WA] / kzA
//   family B:  psi = [(I - Kx Z Kx) VB; -ky Z Kx VB] / kzB,  phi = [0; VB]
// so W = [[0, C], [WA, D]] and V = [[V11, 0], [V21, VB]] (C = B VB KzB^-1, D = -ky Z Kx
// VB KzB^-1, V11 = -WA muA KzA^-1, V21 = ky Kx WA KzA^-1), with block inverses
//   W^-1 = [[ky M1, WA^-1], [KzB (B VB)^-1, 0]]
//   V^-1 = [[-KzA muA^-1 WA^-1, 0], [ky M3, VB^-1]]
// whose N x N blocks do not depend on ky: applying W, V or their inverses to 2N columns
// costs three N x N products and no factorization per direction.
#include "modes.hpp"

#include <cmath>
#include <functional>
#include <optional>

#include "complex_symmetric.hpp"

namespace rcwa {

namespace {

// `fast`: single solves' fast paths (LamellarParts::hermitian) try eig_small (counted in
// `small`) before zgeev.
Eigen eig_near(Mat A, const Mat* guess, int& refined, bool fast, int& small) {
    if (guess)
        if (auto result = eig_from_guess(A, *guess)) {
            ++refined;
            return std::move(*result);
        }
    if (fast)
        if (auto result = eig_small(A)) {
            ++small;
            return std::move(*result);
        }
    return eig(std::move(A));
}

// Rows scaled by conj(d): V = D^H V' back from the moved frame (nothing for an empty d).
void moved_back(Mat& V, const CVec& d) {
    if (d.empty()) return;
    for (int j = 0; j < V.cols; ++j)
        for (int i = 0; i < V.rows; ++i) V(i, j) *= std::conj(d[i]);
}

// C = (C + C^T) / 2: a congruence of a symmetric matrix is symmetric up to round-off, which
// the complex-symmetric solver must not see.
void symmetrize(Mat& C) {
    for (int j = 0; j < C.cols; ++j)
        for (int i = j + 1; i < C.rows; ++i) C(i, j) = C(j, i) = 0.5 * (C(i, j) + C(j, i));
}

// The TM pencil Bm v = mu F v of two symmetric matrices (the moved frame) as a symmetric
// standard problem through a factor G G^T (symmetric_factor), unrefined: of F itself
// (`G_of_exx` false), C = G^-1 Bm G^-T and v = G^-T y; of Exx = F^-1 (`G_of_exx`),
// C = G^T Bm G and v = G y.
std::optional<Eigen> congruent_eigen(const Mat& G, const Mat& Bm, bool G_of_exx) {
    Mat C = Bm;
    if (G_of_exx) {
        triangular_multiply(G, C, 'R', 'N');
        triangular_multiply(G, C, 'L', 'T');
    } else {
        triangular_solve(G, C, 'L', 'N');
        triangular_solve(G, C, 'R', 'T');
    }
    symmetrize(C);
    auto e = eig_complex_symmetric(std::move(C), kComplexSymmetricTolerance, false);
    if (!e) return std::nullopt;
    if (G_of_exx)
        triangular_multiply(G, e->vectors, 'L', 'N');
    else
        triangular_solve(G, e->vectors, 'L', 'T');
    return e;
}

// Refinement of TM eigenvectors V (BV = Bm V) by `correction` (V, BV, values -> the
// first-order correction I + P, updating the values; nothing for a close pair), at most
// kTmRefinementSteps steps, each followed by unit columns and the probed residual
// ||M V x - N V mu x|| <= kComplexSymmetricTolerance ||M V x||; a second step where the
// first falls short (the vectors mapped back through G carry its growth: on the CD at 121
// orders one step left 1e-13 to 1e-10 in 8 of 117 directions). Returns the refined
// decomposition and Bm V in `B_VB`, or nothing.
constexpr int kTmRefinementSteps = 2;
using Apply = std::function<CVec(const CVec&)>;
std::optional<Eigen> refined_until_accepted(Eigen e, Mat BV,
                                            const std::function<std::optional<Mat>(const Mat&, const Mat&, CVec&)>& correction,
                                            const Apply& apply_M, const Apply& apply_N, Mat& B_VB) {
    for (int step = 0; step < kTmRefinementSteps; ++step) {
        auto P = correction(e.vectors, BV, e.values);
        if (!P) return std::nullopt;
        Mat V = matmul(e.vectors, *P), BV1 = matmul(BV, *P);
        unit_columns(V, {&BV1});
        e.vectors = std::move(V);
        BV = std::move(BV1);
        if (probed_residual_ok(apply_M, e.vectors, e.values, 0.0, kComplexSymmetricTolerance, apply_N)) {
            B_VB = std::move(BV);
            return e;
        }
    }
    return std::nullopt;
}

// TM: MB v = mu v is the pencil Bm v = mu Exx^-1 v of two symmetric matrices (moved by D);
// with Exx' = G G^T, C = G^T Bm' G (congruent_eigen), refined on MB' = Exx' Bm' itself
// (two-sided refinement_step: MB's left eigenvectors are Exx^-1 V = Bm V diag(mu)^-1, as
// MB^T = Bm Exx, so L = Bm V up to a scaling of columns that the step does not see).
// Returns VB = D^H V' and B_VB = D^H Bm' V' = Bm VB.
std::optional<Eigen> tm_complex_symmetric(const Mat& Exx, const Mat& Bm, const CVec& d, Mat& B_VB) {
    const Mat Exx_moved = moved_by_phase(Exx, d), Bm_moved = moved_by_phase(Bm, d);
    auto G = symmetric_factor(Exx_moved);
    if (!G) return std::nullopt;
    auto e = congruent_eigen(*G, Bm_moved, true);
    if (!e) return std::nullopt;
    auto correction = [&](const Mat& V, const Mat& BV, CVec& values) {
        return refinement_step(BV, V, matmul(Exx_moved, BV), values);
    };
    auto apply = [&](const CVec& x) { return matvec(Exx_moved, matvec(Bm_moved, x)); };
    Mat BV = matmul(Bm_moved, e->vectors);
    e = refined_until_accepted(std::move(*e), std::move(BV), correction, apply, {}, B_VB);
    if (!e) return std::nullopt;
    moved_back(e->vectors, d);
    moved_back(B_VB, d);
    return e;
}

// TM from F = [[1/eps]] (Li's rule) without forming Exx = F^-1: the pencil Bm v = mu F v of
// two symmetric matrices (moved by D); F' = G G^T, C = G^-1 Bm' G^-T (congruent_eigen).
// Refined on the pencil itself (refinement_from with K = V^T Bm' V, S = V^T F' V), accepted
// on ||Bm' v - mu F' v||. Returns VB = D^H V' and B_VB = D^H Bm' V' = Bm VB.
std::optional<Eigen> tm_complex_symmetric_pencil(const Mat& F, const Mat& Bm, const CVec& d, Mat& B_VB) {
    const Mat F_moved = moved_by_phase(F, d), Bm_moved = moved_by_phase(Bm, d);
    auto G = symmetric_factor(F_moved);
    if (!G) return std::nullopt;
    auto e = congruent_eigen(*G, Bm_moved, false);
    if (!e) return std::nullopt;
    const int n = Bm.rows;
    auto correction = [&](const Mat& V, const Mat& BV, CVec& values) {
        Mat both(n, 2 * n), KS(n, 2 * n);  // [K S] = V^T [Bm' V, F' V]
        std::copy(BV.data.begin(), BV.data.end(), both.data.begin());
        gemm_block(n, n, n, 1.0, F_moved.ptr(), n, V.ptr(), n, 0.0, both.ptr() + static_cast<std::ptrdiff_t>(n) * n, n);
        gemm(V, both, KS, 1.0, 0.0, 'T', 'N');
        return refinement_from(KS, values);
    };
    auto apply_B = [&](const CVec& x) { return matvec(Bm_moved, x); };
    auto apply_F = [&](const CVec& x) { return matvec(F_moved, x); };
    Mat BV = matmul(Bm_moved, e->vectors);
    e = refined_until_accepted(std::move(*e), std::move(BV), correction, apply_B, apply_F, B_VB);
    if (!e) return std::nullopt;
    moved_back(e->vectors, d);
    moved_back(B_VB, d);
    return e;
}

// The complex-symmetric fast path (complex_symmetric.hpp) for a layer whose matrices D E D^H,
// D Exx D^H, D Z D^H are symmetric (`d`: symmetric_by_phase). TE: MA' = D MA D^H, WA = D^H WA'.
std::optional<Eigen> te_complex_symmetric(const std::vector<double>& kx, const Mat& E, const CVec& d) {
    Mat MA = moved_by_phase(E, d);
    for (std::size_t i = 0; i < kx.size(); ++i) MA(static_cast<int>(i), static_cast<int>(i)) -= kx[i] * kx[i];
    auto e = eig_complex_symmetric(std::move(MA));
    if (e) moved_back(e->vectors, d);
    return e;
}

}  // namespace

LamellarEigen lamellar_eigen(const std::vector<double>& kx, const Mat& E, const Mat& Exx_given, const Mat& Z,
                             const LamellarEigen* near, const LamellarParts& parts, const Mat* inv_eps) {
    const int n = static_cast<int>(kx.size());
    LamellarEigen out;
    out.kx = kx;
    // Exx = [[1/eps]]^-1 formed only where a path needs it (an LU inverse, 0.15-0.2 ms at 61
    // harmonics): given [[1/eps]] instead (inv_eps, Exx_given empty), the complex-symmetric TM
    // path works with it directly (tm_complex_symmetric_pencil).
    const bool from_inv_eps = parts.tm && Exx_given.rows == 0 && inv_eps;
    Mat exx_formed;
    auto exx = [&]() -> const Mat& {
        if (!from_inv_eps) return Exx_given;
        if (exx_formed.rows == 0) exx_formed = LU(*inv_eps).inverse();
        return exx_formed;
    };
    const bool lossless = parts.hermitian && !near && is_hermitian(E, kHermitianTolerance);
    const bool tm_pencil = lossless && parts.tm && is_hermitian(exx(), kHermitianTolerance);
    // The complex-symmetric path (LamellarParts::complex_symmetric): the phase that makes E,
    // Exx and Z symmetric, found once where a general eigen-solve is about to run.
    bool phase_tried = false;
    std::optional<CVec> phase;
    auto symmetric_phase = [&]() -> const std::optional<CVec>& {
        if (!phase_tried && parts.complex_symmetric && n < kComplexSymmetricMax) {
            std::vector<const Mat*> mats{&E};
            if (parts.tm) {
                mats.push_back(from_inv_eps ? inv_eps : &Exx_given);  // [[1/eps]] is symmetric where Exx is
                mats.push_back(&Z);
            }
            phase = symmetric_by_phase(mats, kSymmetricTolerance);
        }
        phase_tried = true;
        return phase;
    };
    // Real arithmetic where moving the origin makes the matrices real (real_by_phase: a
    // layer symmetric about some point; every P2-like stripe is): the same decompositions
    // with dsyevd / dsygvd at about a third of the cost, then D^H back.
    std::optional<RealForm> real;
    if (lossless && (!parts.tm || tm_pencil)) {
        std::vector<const Mat*> mats{&E};
        if (parts.tm) {
            mats.push_back(&exx());
            mats.push_back(&Z);
        }
        real = real_by_phase(mats, kRealTolerance);
    }
    if (parts.te && real) {
        RMat MA = real->real[0];
        for (int i = 0; i < n; ++i) MA(i, i) -= kx[i] * kx[i];
        RealEigen ea = eig_symmetric(std::move(MA));
        out.WA = Mat(n, n);
        out.WA_inv = Mat(n, n);
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const double w = ea.vectors(i, j);
                out.WA(i, j) = std::conj(real->d[i]) * w;  // W = D^H W'
                out.WA_inv(j, i) = w * real->d[i];         // W^H = W'^T D
            }
        out.muA.assign(ea.values.begin(), ea.values.end());
        ++out.hermitian;
        ++out.real;
    } else if (parts.te) {
        Mat MA = E;
        for (int i = 0; i < n; ++i) MA(i, i) -= kx[i] * kx[i];
        if (lossless) {
            Eigen ea = eig_hermitian(std::move(MA));
            out.WA_inv = adjoint(ea.vectors);
            out.WA = std::move(ea.vectors);
            out.muA = std::move(ea.values);
            ++out.hermitian;
        } else {
            std::optional<Eigen> cs;
            if (const auto& d = symmetric_phase()) cs = te_complex_symmetric(kx, E, *d);
            if (cs) ++out.complex_symmetric;
            Eigen ea = cs ? std::move(*cs)
                          : eig_near(std::move(MA), near ? &near->WA : nullptr, out.refined, parts.hermitian,
                                     out.inverse_iteration);
            out.WA = std::move(ea.vectors);
            out.muA = std::move(ea.values);
            if (parts.inverses) out.WA_inv = LU(out.WA).inverse();
        }
    }
    std::optional<RealEigen> real_pencil;
    RMat exx_w;  // Exx' W' (real)
    if (parts.tm && real) {
        const RMat& Er = real->real[1];
        RMat Bm = real->real[2];  // I - Kx Z' Kx
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) Bm(i, j) = (i == j ? 1.0 : 0.0) - kx[i] * Bm(i, j) * kx[j];
        real_pencil = eig_symmetric_definite(matmul(Er, matmul(Bm, Er)), Er);
        if (real_pencil) exx_w = matmul(Er, real_pencil->vectors);
    }
    if (real_pencil) {
        // As the complex pencil below with W = D^H W': VB = D^H Exx' W', VB^-1 = W'^T D,
        // B VB = W mu, (B VB)^-1 = mu^-1 (Exx' W')^T D (Exx' symmetric).
        const RMat& W = real_pencil->vectors;
        out.muB.assign(real_pencil->values.begin(), real_pencil->values.end());
        out.VB = Mat(n, n);
        out.VB_inv = Mat(n, n);
        out.B_VB = Mat(n, n);
        out.B_VB_inv = Mat(n, n);
        for (int j = 0; j < n; ++j) {
            const double mu = real_pencil->values[j];
            for (int i = 0; i < n; ++i) {
                const cplx dc = std::conj(real->d[i]);
                out.VB(i, j) = dc * exx_w(i, j);
                out.VB_inv(j, i) = W(i, j) * real->d[i];
                out.B_VB(i, j) = dc * (W(i, j) * mu);
                out.B_VB_inv(j, i) = exx_w(i, j) * real->d[i] / mu;
            }
        }
        ++out.hermitian;
        ++out.real;
        if (parts.conical) {
            Mat KxVB = out.VB;
            for (int j = 0; j < n; ++j)
                for (int i = 0; i < n; ++i) KxVB(i, j) *= kx[i];
            out.ZKx_VB = matmul(Z, KxVB);
        }
    } else if (parts.tm) {
        Mat Bm(n, n);  // I - Kx Z Kx
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) Bm(i, j) = (i == j ? 1.0 : 0.0) - kx[i] * Z(i, j) * kx[j];
        std::optional<Eigen> pencil;
        if (tm_pencil)
            pencil = eig_hermitian_definite(matmul(exx(), matmul(Bm, exx())), exx());
        if (pencil) {
            // v = Exx w with W^H Exx W = I: VB^-1 = W^H; B VB = W mu (from Exx B Exx W = Exx W mu).
            const Mat& W = pencil->vectors;
            out.muB = pencil->values;
            out.VB = matmul(exx(), W);
            out.VB_inv = adjoint(W);
            out.B_VB = W;
            Mat mu_inv_WH = out.VB_inv;  // mu^-1 W^H
            for (int j = 0; j < n; ++j)
                for (int i = 0; i < n; ++i) {
                    out.B_VB(i, j) *= out.muB[j];
                    mu_inv_WH(i, j) /= out.muB[i];
                }
            if (parts.inverses) out.B_VB_inv = matmul(mu_inv_WH, exx());  // (W mu)^-1 = mu^-1 W^H Exx
            ++out.hermitian;
        } else {
            std::optional<Eigen> cs;
            bool tm_cs = false;
            if (const auto& d = symmetric_phase())
                cs = from_inv_eps ? tm_complex_symmetric_pencil(*inv_eps, Bm, *d, out.B_VB)
                                  : tm_complex_symmetric(Exx_given, Bm, *d, out.B_VB);
            if (cs) {
                tm_cs = true;
                ++out.complex_symmetric;
            }
            Eigen eb = cs ? std::move(*cs)
                          : eig_near(matmul(exx(), Bm), near ? &near->VB : nullptr, out.refined, parts.hermitian,
                                     out.inverse_iteration);
            out.VB = std::move(eb.vectors);
            out.muB = std::move(eb.values);
            if (!tm_cs) out.B_VB = matmul(Bm, out.VB);
            if (parts.inverses) {
                out.VB_inv = LU(out.VB).inverse();
                out.B_VB_inv = LU(out.B_VB).inverse();
            }
        }
        if (parts.conical) {  // used only with ky != 0 (LamellarModes' D block, M1)
            Mat KxVB = out.VB;
            for (int j = 0; j < n; ++j)
                for (int i = 0; i < n; ++i) KxVB(i, j) *= kx[i];
            out.ZKx_VB = matmul(Z, KxVB);
        }
    }
    out.inverses = parts.inverses;
    if (parts.te && parts.tm && parts.conical && parts.inverses) {
        out.M1 = matmul(out.WA_inv, matmul(out.ZKx_VB, out.B_VB_inv));
        Mat KxWA_mu = out.WA;  // Kx WA muA^-1
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) KxWA_mu(i, j) *= kx[i] / out.muA[j];
        out.M3 = matmul(out.VB_inv, matmul(KxWA_mu, out.WA_inv));
    }
    return out;
}

namespace {

// Top (rows 0..N-1) and bottom (N..2N-1) halves of a 2N-row matrix, and back.
Mat rows(const Mat& B, int first, int count) {
    Mat out(count, B.cols);
    for (int j = 0; j < B.cols; ++j)
        for (int i = 0; i < count; ++i) out(i, j) = B(first + i, j);
    return out;
}
Mat stacked(const Mat& top, const Mat& bottom) {
    Mat out(top.rows + bottom.rows, top.cols);
    for (int j = 0; j < top.cols; ++j) {
        for (int i = 0; i < top.rows; ++i) out(i, j) = top(i, j);
        for (int i = 0; i < bottom.rows; ++i) out(top.rows + i, j) = bottom(i, j);
    }
    return out;
}
Mat scaled_rows(Mat M, const CVec& d, int offset = 0, bool invert = false) {
    for (int j = 0; j < M.cols; ++j)
        for (int i = 0; i < M.rows; ++i) M(i, j) = invert ? M(i, j) / d[offset + i] : M(i, j) * d[offset + i];
    return M;
}

class LamellarModes : public LayerModes {
  public:
    LamellarModes(const LamellarEigen& e, double ky) : e_(e), ky_(ky), n_(static_cast<int>(e.kx.size())) {
        kz_.resize(2 * static_cast<std::size_t>(n_));
        for (int i = 0; i < n_; ++i) {
            kz_[i] = layer_kz(e.muA[i] - ky * ky);
            kz_[n_ + i] = layer_kz(e.muB[i] - ky * ky);
        }
    }

    Mat apply_W(const Mat& B) const override {  // [[0, C], [WA, D]]
        const Mat y = scaled_rows(rows(B, n_, n_), kz_, n_, true);  // KzB^-1 B_bottom
        Mat bottom = matmul(e_.WA, rows(B, 0, n_));
        gemm(e_.ZKx_VB, y, bottom, -ky_, 1.0);
        return stacked(matmul(e_.B_VB, y), bottom);
    }
    Mat apply_V(const Mat& B) const override {  // [[V11, 0], [V21, VB]]
        const Mat y = scaled_rows(rows(B, 0, n_), kz_, 0, true);  // KzA^-1 B_top
        const Mat wy = matmul(e_.WA, y);
        Mat top = matmul(e_.WA, scaled_rows(y, e_.muA));
        for (auto& v : top.data) v = -v;
        Mat bottom = matmul(e_.VB, rows(B, n_, n_));
        for (int j = 0; j < B.cols; ++j)
            for (int i = 0; i < n_; ++i) bottom(i, j) += ky_ * e_.kx[i] * wy(i, j);
        return stacked(top, bottom);
    }
    Mat apply_W_inverse(const Mat& B) const override {  // [[ky M1, WA^-1], [KzB (B VB)^-1, 0]]
        const Mat top_in = rows(B, 0, n_);
        Mat top = matmul(e_.WA_inv, rows(B, n_, n_));
        gemm(e_.M1, top_in, top, ky_, 1.0);
        return stacked(top, scaled_rows(matmul(e_.B_VB_inv, top_in), kz_, n_));
    }
    Mat apply_V_inverse(const Mat& B) const override {  // [[-KzA muA^-1 WA^-1, 0], [ky M3, VB^-1]]
        const Mat top_in = rows(B, 0, n_);
        Mat top = matmul(e_.WA_inv, top_in);
        for (int j = 0; j < top.cols; ++j)
            for (int i = 0; i < n_; ++i) top(i, j) *= -kz_[i] / e_.muA[i];
        Mat bottom = matmul(e_.VB_inv, rows(B, n_, n_));
        gemm(e_.M3, top_in, bottom, ky_, 1.0);
        return stacked(top, bottom);
    }

    Mat W() const override {
        Mat out(2 * n_, 2 * n_);
        for (int j = 0; j < n_; ++j) {
            const cplx inv_kzB = 1.0 / kz_[n_ + j];  // one division a column
            const cplx d = -ky_ * inv_kzB;
            for (int i = 0; i < n_; ++i) {
                out(i, n_ + j) = e_.B_VB(i, j) * inv_kzB;
                out(n_ + i, j) = e_.WA(i, j);
                out(n_ + i, n_ + j) = d * e_.ZKx_VB(i, j);
            }
        }
        return out;
    }
    Mat V() const override {
        Mat out(2 * n_, 2 * n_);
        for (int j = 0; j < n_; ++j) {
            const cplx scale = 1.0 / kz_[j];
            for (int i = 0; i < n_; ++i) {
                out(i, j) = -e_.WA(i, j) * e_.muA[j] * scale;
                out(n_ + i, j) = ky_ * e_.kx[i] * e_.WA(i, j) * scale;
                out(n_ + i, n_ + j) = e_.VB(i, j);
            }
        }
        return out;
    }
    Mat W_inverse() const override {
        Mat out(2 * n_, 2 * n_);
        for (int j = 0; j < n_; ++j)
            for (int i = 0; i < n_; ++i) {
                out(i, j) = ky_ * e_.M1(i, j);
                out(i, n_ + j) = e_.WA_inv(i, j);
                out(n_ + i, j) = kz_[n_ + i] * e_.B_VB_inv(i, j);
            }
        return out;
    }
    bool dense() const override { return !e_.inverses; }
    Mat V_inverse() const override {
        Mat out(2 * n_, 2 * n_);
        for (int j = 0; j < n_; ++j)
            for (int i = 0; i < n_; ++i) {
                out(i, j) = -kz_[i] / e_.muA[i] * e_.WA_inv(i, j);
                out(n_ + i, j) = ky_ * e_.M3(i, j);
                out(n_ + i, n_ + j) = e_.VB_inv(i, j);
            }
        return out;
    }

  private:
    const LamellarEigen& e_;
    double ky_;
    int n_;
};

}  // namespace

std::unique_ptr<LayerModes> lamellar_modes(const std::vector<double>&, const LamellarEigen& e, double ky) {
    return std::make_unique<LamellarModes>(e, ky);
}

}  // namespace rcwa
