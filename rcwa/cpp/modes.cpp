#include "modes.hpp"

#include <algorithm>
#include <cmath>

namespace rcwa {

cplx outgoing_sqrt(cplx kz2) {
    if (kz2.imag() == 0.0) {
        const double x = kz2.real();
        return x >= 0.0 ? cplx(std::sqrt(x), 0.0) : cplx(0.0, std::sqrt(-x));
    }
    cplx r = std::sqrt(kz2);
    if (r.imag() < 0.0 || (r.imag() == 0.0 && r.real() < 0.0)) r = -r;
    return r;
}

cplx layer_kz(cplx kz2) {
    // Eigenvalues of a lossless layer carry round-off imaginary parts of either sign.
    // The outgoing rule (Im >= 0) would then flip some propagating modes to Re(kz) < 0,
    // labelling an up-going wave "down-going"; the S-matrix does not mind, but the
    // enhanced transmittance method matches the substrate's down-going field onto the
    // layer's down-going modes and breaks (an 18% energy error was found by hypothesis).
    // So: the principal root (Re >= 0), flipped only when Im(kz) is clearly negative
    // (evanescent or lossy modes), never for round-off on a propagating mode.
    cplx r = std::sqrt(kz2);
    if (r.imag() < -1e-8 * std::max(1.0, std::abs(r))) r = -r;
    return regularize_kz(r);
}

cplx regularize_kz(cplx kz) {
    // At kz = 0 exactly the two modes of a finite layer coincide and the mode matrix
    // [W W; V -V] is singular. Moving kz to |kz| = 1e-8 (a relative change of the
    // permittivity of order 1e-16) keeps it invertible; the error this makes is of order
    // 1e-8 in the efficiencies (sqrt(machine epsilon), the best trade between the
    // perturbation and the cancellation it causes). Only finite layers need this.
    if (std::abs(kz) >= kKzFloor) return kz;
    return cplx(kKzFloor, kKzFloor) / std::sqrt(2.0);
}

namespace {

// Uniform layer: per order i the 2 x 2 block of Q is
//   [[-kx ky, kx^2 - eps], [eps - ky^2, kx ky]],  V = Q / kz,  V^{-1} = kz Q^{-1},
//   Q^{-1} = [[kx ky, eps - kx^2], [ky^2 - eps, -kx ky]] / (eps kz^2).
class UniformModes : public LayerModes {
  public:
    UniformModes(const Harmonics& h, cplx eps) : h_(h), eps_(h.size(), eps) {
        const int n = h.size();
        kz_.resize(2 * static_cast<std::size_t>(n));
        for (int i = 0; i < n; ++i) {
            const double kt2 = h.kx[i] * h.kx[i] + h.ky[i] * h.ky[i];
            const cplx kz = regularize_kz(outgoing_sqrt(eps - kt2));
            // Where kz was moved off zero, move this order's permittivity with it
            // (by |kz|^2 = 1e-16), so that V and V^{-1} stay exact inverses.
            eps_[i] = kz * kz + kt2;
            kz_[i] = kz;
            kz_[n + i] = kz;
        }
    }
    Mat apply_W(const Mat& B) const override { return B; }
    Mat apply_W_inverse(const Mat& B) const override { return B; }
    Mat apply_V(const Mat& B) const override { return blockwise(B, false); }
    Mat apply_V_inverse(const Mat& B) const override { return blockwise(B, true); }

  private:
    Mat blockwise(const Mat& B, bool inverse) const {
        const int n = h_.size();
        Mat out(B.rows, B.cols);
        for (int i = 0; i < n; ++i) {
            const double kx = h_.kx[i], ky = h_.ky[i];
            const cplx kz = kz_[i], eps = eps_[i];
            cplx a, b, c, d;
            if (!inverse) {
                a = -kx * ky / kz;
                b = (kx * kx - eps) / kz;
                c = (eps - ky * ky) / kz;
                d = kx * ky / kz;
            } else {
                const cplx s = 1.0 / (eps * kz);
                a = kx * ky * s;
                b = (eps - kx * kx) * s;
                c = (ky * ky - eps) * s;
                d = -kx * ky * s;
            }
            for (int j = 0; j < B.cols; ++j) {
                const cplx x = B(i, j), y = B(n + i, j);
                out(i, j) = a * x + b * y;
                out(n + i, j) = c * x + d * y;
            }
        }
        return out;
    }
    Harmonics h_;
    CVec eps_;  // per order (equal to the layer's except where kz was regularized)
};

}  // namespace

std::unique_ptr<LayerModes> uniform_modes(const Harmonics& h, cplx eps) {
    return std::make_unique<UniformModes>(h, eps);
}

DenseModes::DenseModes(Mat W, Mat V, CVec kz) : W_(std::move(W)), V_(std::move(V)) { kz_ = std::move(kz); }

Mat q_matrix(const Harmonics& h, const Mat& Exx, const Mat& Exy, const Mat& Eyx, const Mat& Eyy) {
    const int n = h.size();
    Mat Q(2 * n, 2 * n);
    for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
            Q(i, j) = -Eyx(i, j);
            Q(n + i, j) = Exx(i, j);
        }
        for (int i = 0; i < n; ++i) {
            Q(i, n + j) = -Eyy(i, j);
            Q(n + i, n + j) = Exy(i, j);
        }
        Q(j, j) -= h.kx[j] * h.ky[j];
        Q(j, n + j) += h.kx[j] * h.kx[j];
        Q(n + j, j) -= h.ky[j] * h.ky[j];
        Q(n + j, n + j) += h.ky[j] * h.kx[j];
    }
    return Q;
}

void pq_matrices(const Harmonics& h, const Mat& Z, const Mat& Exx, const Mat& Exy, const Mat& Eyx, const Mat& Eyy,
                 Mat& P, Mat& Q) {
    const int n = h.size();
    P = Mat(2 * n, 2 * n);
    for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
            const cplx z = Z(i, j);
            P(i, j) = h.kx[i] * z * h.ky[j];
            P(i, n + j) = -h.kx[i] * z * h.kx[j];
            P(n + i, j) = h.ky[i] * z * h.ky[j];
            P(n + i, n + j) = -h.ky[i] * z * h.kx[j];
        }
        P(j, n + j) += 1.0;
        P(n + j, j) -= 1.0;
    }
    Q = q_matrix(h, Exx, Exy, Eyx, Eyy);
}

Mat pq_product(const Harmonics& h, const Mat& Z, const Mat& Q) {
    // P = [Kx; Ky] Z [Ky, -Kx] + [[0, I], [-I, 0]] (pq_matrices), so
    // P Q = [Kx; Ky] (Z S) + [Q_bottom; -Q_top] with S = Ky Q_top - Kx Q_bottom (N x 2N):
    // one N x N by N x 2N product instead of a 2N x 2N one (a quarter of the work).
    const int n = h.size();
    Mat S(n, 2 * n);
    for (int j = 0; j < 2 * n; ++j)
        for (int i = 0; i < n; ++i) S(i, j) = h.ky[i] * Q(i, j) - h.kx[i] * Q(n + i, j);
    Mat PQ(2 * n, 2 * n);
    gemm_block(n, 2 * n, n, 1.0, Z.ptr(), n, S.ptr(), n, 0.0, PQ.ptr(), 2 * n);  // T = Z S in PQ's top half
    for (int j = 0; j < 2 * n; ++j)
        for (int i = 0; i < n; ++i) {
            const cplx t = PQ(i, j);
            PQ(i, j) = h.kx[i] * t + Q(n + i, j);
            PQ(n + i, j) = h.ky[i] * t - Q(i, j);
        }
    return PQ;
}

namespace {

bool is_zero(const Mat& A) {
    for (const cplx& v : A.data)
        if (v != 0.0) return false;
    return true;
}

// V = Q W diag(kz)^-1 (modes.hpp). Where the tensor has no off-diagonal blocks (Exy = Eyx =
// 0: Laurent's rule, and Li's in 2D, which the rectangle-only cells use), with W = [Wx; Wy],
// Q W = [-Eyy Wy + diag(-kx ky) Wx + diag(kx^2) Wy; Exx Wx - diag(ky^2) Wx + diag(ky kx) Wy]:
// two N x N by N x 2N products on W's halves in place instead of one 2N x 2N square one,
// half the work, equal to matmul(Q, W) to round-off.
Mat mode_V(const Harmonics& h, const Mat& Q, const Mat& Exx, const Mat& Exy, const Mat& Eyx, const Mat& Eyy,
           const Mat& W, const CVec& kz) {
    const int n = h.size(), n2 = 2 * n, cols = W.cols;
    CVec inv_kz(kz.size());
    for (std::size_t j = 0; j < kz.size(); ++j) inv_kz[j] = 1.0 / kz[j];  // one division a column, not one an entry
    if (!is_zero(Exy) || !is_zero(Eyx)) {
        Mat V = matmul(Q, W);
        for (int j = 0; j < cols; ++j)
            for (int i = 0; i < n2; ++i) V(i, j) *= inv_kz[j];
        return V;
    }
    Mat V(n2, cols);
    gemm_block(n, cols, n, -1.0, Eyy.ptr(), n, W.ptr() + n, n2, 0.0, V.ptr(), n2);
    gemm_block(n, cols, n, 1.0, Exx.ptr(), n, W.ptr(), n2, 0.0, V.ptr() + n, n2);
    for (int j = 0; j < cols; ++j)
        for (int i = 0; i < n; ++i) {
            const double kx = h.kx[i], ky = h.ky[i];
            const cplx wx = W(i, j), wy = W(n + i, j);
            V(i, j) = (V(i, j) - kx * ky * wx + kx * kx * wy) * inv_kz[j];
            V(n + i, j) = (V(n + i, j) - ky * ky * wx + ky * kx * wy) * inv_kz[j];
        }
    return V;
}

}  // namespace

std::unique_ptr<LayerModes> general_modes(const Harmonics& h, const Mat& Z, const Mat& Exx,
                                          const Mat& Exy, const Mat& Eyx, const Mat& Eyy) {
    const int n = h.size();
    const Mat Q = q_matrix(h, Exx, Exy, Eyx, Eyy);
    Eigen e = eig(pq_product(h, Z, Q));
    CVec kz(2 * static_cast<std::size_t>(n));
    for (int i = 0; i < 2 * n; ++i) kz[i] = layer_kz(e.values[i]);
    Mat V = mode_V(h, Q, Exx, Exy, Eyx, Eyy, e.vectors, kz);
    return std::make_unique<DenseModes>(std::move(e.vectors), std::move(V), std::move(kz));
}

}  // namespace rcwa
