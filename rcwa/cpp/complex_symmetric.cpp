#include "complex_symmetric.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

#define lapack_complex_float std::complex<float>
#define lapack_complex_double std::complex<double>
#include "cblas.h"
#include "lapacke.h"

namespace rcwa {

namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

// The reduction Q^T A Q = tridiag(e, d, e), Q = H_0 ... H_{n-3}, H_k = I - tau_k v_k v_k^T
// acting on rows k+1.. (v_k kept in A's column k below the diagonal).
struct Tridiagonal {
    CVec d, e, tau;
};

std::optional<Tridiagonal> tridiagonalize(Mat& A) {
    const int n = A.rows;
    Tridiagonal t;
    t.d.resize(static_cast<std::size_t>(n));
    t.e.assign(static_cast<std::size_t>(std::max(n - 1, 0)), 0.0);
    t.tau.assign(static_cast<std::size_t>(std::max(n - 2, 0)), 0.0);
    CVec p(static_cast<std::size_t>(n)), vw(2 * static_cast<std::size_t>(n)), wv(2 * static_cast<std::size_t>(n));
    for (int k = 0; k + 2 < n; ++k) {
        const int m = n - k - 1;
        cplx* v = &A(k + 1, k);
        double tail = 0.0;
        for (int i = 1; i < m; ++i) tail += std::norm(v[i]);
        if (tail == 0.0) {  // already tridiagonal in this column
            t.e[k] = v[0];
            continue;
        }
        cplx xx = 0.0;
        for (int i = 0; i < m; ++i) xx += v[i] * v[i];
        cplx alpha = std::sqrt(xx);
        if ((std::conj(alpha) * v[0]).real() > 0.0) alpha = -alpha;  // |alpha - x_0| the larger
        v[0] -= alpha;
        cplx vv = 0.0;
        double v2 = 0.0;
        for (int i = 0; i < m; ++i) {
            vv += v[i] * v[i];
            v2 += std::norm(v[i]);
        }
        if (!(v2 <= kComplexSymmetricGrowth * std::abs(vv))) return std::nullopt;  // v^T v ~ 0: breakdown
        const cplx tau = 2.0 * std::conj(vv) / std::norm(vv);
        cplx* S = &A(k + 1, k + 1);
        const cplx zero = 0.0, minus_one = -1.0;
        // p = tau S v, w = p - (tau / 2) (p^T v) v, S <- S - v w^T - w v^T.
        scipy_cblas_zgemv(CblasColMajor, CblasNoTrans, m, m, &tau, S, n, v, 1, &zero, p.data(), 1);
        cplx pv = 0.0;
        for (int i = 0; i < m; ++i) pv += p[i] * v[i];
        const cplx beta = -0.5 * tau * pv;
        for (int i = 0; i < m; ++i) {
            p[i] += beta * v[i];
            vw[i] = v[i];
            vw[m + i] = p[i];
            wv[2 * i] = p[i];  // [w v]^T, 2 x m
            wv[2 * i + 1] = v[i];
        }
        const cplx one = 1.0;
        scipy_cblas_zgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, m, m, 2, &minus_one, vw.data(), m, wv.data(), 2,
                          &one, S, n);
        t.e[k] = alpha;
        t.tau[k] = tau;
    }
    for (int i = 0; i < n; ++i) t.d[i] = A(i, i);
    if (n >= 2) t.e[n - 2] = A(n - 1, n - 2);
    return t;
}

// |Re| + |Im| (LAPACK's cabs1): the size tests below, without hypot.
inline double cabs1(cplx z) { return std::fabs(z.real()) + std::fabs(z.imag()); }

// 1 / z as conj(z) / |z|^2: no scaling against overflow (libgcc's __divdc3 has it, and was a
// tenth of the time); the entries here lie many decades inside the double range.
inline cplx recip(cplx z) {
    const double d = z.real() * z.real() + z.imag() * z.imag();
    return {z.real() / d, -z.imag() / d};
}

// The principal square root (Re >= 0) with one real sqrt and hypot-free modulus: the
// rotations' entries here are far from overflow, and std::sqrt(complex) was most of QL's time.
inline cplx csqrt(cplx z) {
    const double x = z.real(), y = z.imag();
    const double r = std::sqrt(x * x + y * y);
    if (r == 0.0) return 0.0;
    if (x >= 0.0) {
        const double t = std::sqrt(0.5 * (r + x));
        return {t, y / (2.0 * t)};
    }
    const double t = std::sqrt(0.5 * (r - x));
    return {std::fabs(y) / (2.0 * t), y >= 0.0 ? t : -t};
}

// Eigenvalues of the complex symmetric tridiagonal (d, e) by the implicit QL algorithm
// (tql1 with complex rotations), in d. False on a rotation's breakdown or no convergence.
bool tridiagonal_eigenvalues(CVec& d, CVec e) {
    const int n = static_cast<int>(d.size());
    e.push_back(0.0);
    for (int l = 0; l < n; ++l) {
        int iterations = 0;
        for (;;) {
            int m = l;
            for (; m < n - 1; ++m)
                if (cabs1(e[m]) <= 0.5 * kEps * (cabs1(d[m]) + cabs1(d[m + 1]))) break;
            if (m == l) break;
            if (++iterations > 40) return false;
            cplx g = (d[l + 1] - d[l]) * recip(2.0 * e[l]);
            cplx r = csqrt(g * g + 1.0);
            if (std::norm(g - r) > std::norm(g + r)) r = -r;
            g = d[m] - d[l] + e[l] * recip(g + r);
            cplx s = 1.0, c = 1.0, p = 0.0;
            int i = m - 1;
            bool underflow = false;
            for (; i >= l; --i) {
                const cplx f = s * e[i], b = c * e[i];
                const cplx r2 = f * f + g * g;
                const double size = std::norm(f) + std::norm(g);
                if (size == 0.0) {
                    e[i + 1] = 0.0;
                    d[i + 1] -= p;
                    e[m] = 0.0;
                    underflow = true;
                    break;
                }
                // c^2 + s^2 = 1 breaks down where f^2 + g^2 ~ 0 while f, g are not
                if (!(size * size <= kComplexSymmetricGrowth * kComplexSymmetricGrowth * std::norm(r2))) return false;
                r = csqrt(r2);
                e[i + 1] = r;
                const cplx inv = recip(r);
                s = f * inv;
                c = g * inv;
                g = d[i + 1] - p;
                r = (d[i] - g) * s + 2.0 * c * b;
                p = s * r;
                d[i + 1] = g + p;
                g = c * r - b;
            }
            if (underflow) continue;
            d[l] -= p;
            e[l] = g;
            e[m] = 0.0;
        }
    }
    return true;
}

// T - w I = P L U for the tridiagonal T = tridiag(e, d, e) (Gaussian elimination with
// partial pivoting, as zgttrf; U has two superdiagonals), kept with U's reciprocal pivots.
struct TridiagonalLU {
    CVec l, inv_u0, u1, u2;
    std::vector<char> swapped;

    TridiagonalLU(int n)
        : l(static_cast<std::size_t>(n)), inv_u0(static_cast<std::size_t>(n)), u1(static_cast<std::size_t>(n)),
          u2(static_cast<std::size_t>(n)), swapped(static_cast<std::size_t>(n)) {}

    void factor(const CVec& d, const CVec& e, cplx w, double tiny) {
        const int n = static_cast<int>(d.size());
        cplx diag = d[0] - w, upper = n > 1 ? e[0] : 0.0;  // row i's entries at columns i, i+1
        for (int i = 0; i < n; ++i) {
            if (i + 1 == n) {
                if (cabs1(diag) < tiny) diag = tiny;  // w is an eigenvalue: perturb, as dlagtf
                inv_u0[i] = recip(diag);
                u1[i] = u2[i] = 0.0;
                swapped[i] = 0;
                break;
            }
            const cplx below = e[i], next_diag = d[i + 1] - w, next_upper = i + 2 < n ? e[i + 1] : 0.0;
            if (cabs1(diag) >= cabs1(below)) {
                swapped[i] = 0;
                if (cabs1(diag) < tiny) diag = tiny;
                const cplx inv = recip(diag);
                inv_u0[i] = inv;
                u1[i] = upper;
                u2[i] = 0.0;
                l[i] = below * inv;
                diag = next_diag - l[i] * upper;
                upper = next_upper;
            } else {
                swapped[i] = 1;
                const cplx inv = recip(below);
                inv_u0[i] = inv;
                u1[i] = next_diag;
                u2[i] = next_upper;
                l[i] = diag * inv;
                diag = upper - l[i] * next_diag;
                upper = -l[i] * next_upper;
            }
        }
    }
    // y <- (T - w I)^-1 y.
    void solve(CVec& y) const {
        const int n = static_cast<int>(y.size());
        for (int i = 0; i + 1 < n; ++i) {
            if (swapped[i]) std::swap(y[i], y[i + 1]);
            y[i + 1] -= l[i] * y[i];
        }
        for (int i = n - 1; i >= 0; --i) {
            cplx v = y[i];
            if (i + 1 < n) v -= u1[i] * y[i + 1];
            if (i + 2 < n) v -= u2[i] * y[i + 2];
            y[i] = v * inv_u0[i];
        }
    }
};

// Eigenvectors of the tridiagonal (d, e) at eigenvalues w by inverse iteration (two steps
// from a fixed start), in the columns of Y; those of close eigenvalues are made orthogonal
// in the bilinear form y_i^T y_j = 0 (as dstein does in the Euclidean one).
std::optional<Mat> tridiagonal_vectors(const CVec& d, const CVec& e, const CVec& w) {
    const int n = static_cast<int>(d.size());
    double scale = 0.0;
    for (int i = 0; i < n; ++i)
        scale = std::max(scale, cabs1(d[i]) + (i > 0 ? cabs1(e[i - 1]) : 0.0) + (i + 1 < n ? cabs1(e[i]) : 0.0));
    if (scale == 0.0) scale = 1.0;
    const double close = 1e-3 * scale, tiny = kEps * scale;
    std::vector<int> order(static_cast<std::size_t>(n));
    for (int j = 0; j < n; ++j) order[j] = j;
    std::sort(order.begin(), order.end(), [&](int a, int b) { return w[a].real() < w[b].real(); });
    Mat Y(n, n);
    CVec y(static_cast<std::size_t>(n)), start(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i)  // a start with every component present (a fixed pseudo-random sequence)
        start[i] = cplx(1.0 + 0.5 * std::sin(1.7 * i), 0.25 * std::cos(2.3 * i));
    TridiagonalLU lu(n);
    std::vector<int> neighbours;
    for (int jj = 0; jj < n; ++jj) {
        const int j = order[jj];
        lu.factor(d, e, w[j], tiny);
        neighbours.clear();
        for (int kk = jj - 1; kk >= 0 && w[j].real() - w[order[kk]].real() <= close; --kk)
            if (cabs1(w[order[kk]] - w[j]) <= close) neighbours.push_back(order[kk]);
        y = start;
        for (int step = 0; step < 2; ++step) {
            lu.solve(y);
            for (int k : neighbours) {  // bilinear Gram-Schmidt against close eigenvalues' vectors
                cplx yk_y = 0.0;
                for (int i = 0; i < n; ++i) yk_y += Y(i, k) * y[i];
                for (int i = 0; i < n; ++i) y[i] -= yk_y * Y(i, k);  // Y's columns have y^T y = 1
            }
            double norm2 = 0.0;
            for (int i = 0; i < n; ++i) norm2 += std::norm(y[i]);
            if (!(norm2 > 0.0) || !std::isfinite(norm2)) return std::nullopt;
            const double inv = 1.0 / std::sqrt(norm2);
            for (int i = 0; i < n; ++i) y[i] *= inv;
        }
        // Bilinear normalization y^T y = 1 (the Gram-Schmidt above relies on it); a vector
        // with y^T y ~ 0 belongs to an ill-conditioned eigenvalue: decline.
        cplx yy = 0.0;
        for (int i = 0; i < n; ++i) yy += y[i] * y[i];
        if (!(1.0 <= kComplexSymmetricGrowth * std::abs(yy))) return std::nullopt;
        const cplx inv = 1.0 / csqrt(yy);
        for (int i = 0; i < n; ++i) Y(i, j) = y[i] * inv;
    }
    return Y;
}

// Y <- Q Y for Q = H_0 ... H_{n-3} (the reflectors in R's columns below the diagonal).
void apply_reflectors(const Mat& R, const CVec& tau, Mat& Y) {
    const int n = R.rows, cols = Y.cols;
    CVec t(static_cast<std::size_t>(cols));
    const cplx zero = 0.0, one = 1.0;
    for (int k = static_cast<int>(tau.size()) - 1; k >= 0; --k) {
        if (tau[k] == cplx(0.0)) continue;
        const int m = n - k - 1;
        const cplx* v = &R(k + 1, k);
        cplx* Ys = &Y(k + 1, 0);
        // t = Ys^T v, Ys <- Ys - tau v t^T.
        scipy_cblas_zgemv(CblasColMajor, CblasTrans, m, cols, &one, Ys, n, v, 1, &zero, t.data(), 1);
        const cplx minus_tau = -tau[k];
        scipy_cblas_zgeru(CblasColMajor, m, cols, &minus_tau, v, 1, t.data(), 1, Ys, n);
    }
}

double frobenius(const Mat& A) {
    double s = 0.0;
    for (const cplx& a : A.data) s += std::norm(a);
    return std::sqrt(s);
}

}  // namespace

bool is_complex_symmetric(const Mat& A, double tolerance) {
    if (A.rows != A.cols) return false;
    double largest = 0.0, asymmetry = 0.0;
    for (int j = 0; j < A.cols; ++j)
        for (int i = 0; i <= j; ++i) {
            largest = std::max(largest, std::max(std::norm(A(i, j)), std::norm(A(j, i))));
            asymmetry = std::max(asymmetry, std::norm(A(i, j) - A(j, i)));
        }
    return asymmetry <= tolerance * tolerance * largest;
}

std::optional<Eigen> eig_complex_symmetric(Mat A, double tolerance, bool refine) {
    if (A.rows != A.cols) throw std::invalid_argument("eig_complex_symmetric: matrix is not square");
    const int n = A.rows;
    if (n == 0) return Eigen{};
    const Mat A0 = A;
    auto t = tridiagonalize(A);
    if (!t) return std::nullopt;
    CVec w = t->d;
    if (!tridiagonal_eigenvalues(w, t->e)) return std::nullopt;
    auto Y = tridiagonal_vectors(t->d, t->e, w);
    if (!Y) return std::nullopt;
    apply_reflectors(A, t->tau, *Y);
    if (!refine) {
        Eigen out{std::move(w), std::move(*Y)};
        return out;
    }
    // Refinement against A itself: the left eigenvectors are W^T.
    Mat& W = *Y;
    Mat AW = matmul(A0, W);
    Eigen out{std::move(w), Mat()};
    auto P = refinement_step(W, W, AW, out.values);
    if (!P) return std::nullopt;
    out.vectors = matmul(W, *P);
    unit_columns(out.vectors, {});
    const double scale = tolerance * frobenius(A0) * std::sqrt(static_cast<double>(n));  // ||W||_F = sqrt(n)
    auto apply_A = [&](const CVec& x) { return matvec(A0, x); };
    if (!probed_residual_ok(apply_A, out.vectors, out.values, scale, 0.0)) return std::nullopt;
    return out;
}

std::optional<Mat> refinement_step(const Mat& L, const Mat& V, const Mat& MV, CVec& values) {
    const int n = V.rows;
    // [K S] = L^T [M V, V] in one product.
    Mat both(n, 2 * n), KS(n, 2 * n);
    std::copy(MV.data.begin(), MV.data.end(), both.data.begin());
    std::copy(V.data.begin(), V.data.end(), both.data.begin() + static_cast<std::ptrdiff_t>(n) * n);
    gemm(L, both, KS, 1.0, 0.0, 'T', 'N');
    return refinement_from(KS, values);
}

std::optional<Mat> refinement_from(const Mat& KS, CVec& values) {
    const int n = KS.rows;
    auto K = [&](int i, int j) { return KS(i, j); };
    auto S = [&](int i, int j) { return KS(i, n + j); };
    for (int j = 0; j < n; ++j) {
        if (!(cabs1(S(j, j)) > 0.0)) return std::nullopt;
        values[j] = K(j, j) * recip(S(j, j));
    }
    Mat P(n, n);
    for (int j = 0; j < n; ++j) {
        P(j, j) = 1.0;
        for (int i = 0; i < n; ++i) {
            if (i == j) continue;
            const cplx num = K(i, j) - values[j] * S(i, j);
            const cplx gap = (values[j] - values[i]) * S(i, i);
            if (num == cplx(0.0)) continue;  // already orthogonal (also an exactly repeated eigenvalue)
            if (!(cabs1(num) <= 1e-2 * cabs1(gap))) return std::nullopt;  // a pair it cannot separate
            P(i, j) = num * recip(gap);
        }
    }
    return P;
}

CVec matvec(const Mat& A, const CVec& x) {
    CVec y(static_cast<std::size_t>(A.rows));
    const cplx one = 1.0, zero = 0.0;
    if (A.rows > 0 && A.cols > 0)
        scipy_cblas_zgemv(CblasColMajor, CblasNoTrans, A.rows, A.cols, &one, A.ptr(), A.rows, x.data(), 1, &zero,
                          y.data(), 1);
    return y;
}

void unit_columns(Mat& V, std::vector<Mat*> alongside) {
    for (int j = 0; j < V.cols; ++j) {
        double norm2 = 0.0;
        for (int i = 0; i < V.rows; ++i) norm2 += std::norm(V(i, j));
        const double inv = norm2 > 0.0 ? 1.0 / std::sqrt(norm2) : 1.0;
        for (int i = 0; i < V.rows; ++i) V(i, j) *= inv;
        for (Mat* M : alongside)
            for (int i = 0; i < M->rows; ++i) (*M)(i, j) *= inv;
    }
}

bool probed_residual_ok(const std::function<CVec(const CVec&)>& apply_M, const Mat& V, const CVec& values,
                        double absolute, double relative, const std::function<CVec(const CVec&)>& apply_N) {
    const int n = V.rows, m = V.cols;
    const cplx one = 1.0, zero = 0.0;
    CVec x(static_cast<std::size_t>(m)), wx(static_cast<std::size_t>(m)), v(static_cast<std::size_t>(n)),
        vw(static_cast<std::size_t>(n));
    unsigned state = 12345u;
    for (int probe = 0; probe < 2; ++probe) {
        for (int j = 0; j < m; ++j) {  // random signs (a fixed linear congruential sequence)
            state = state * 1664525u + 1013904223u;
            x[j] = (state >> 31) ? 1.0 : -1.0;
            wx[j] = values[j] * x[j];
        }
        scipy_cblas_zgemv(CblasColMajor, CblasNoTrans, n, m, &one, V.ptr(), n, x.data(), 1, &zero, v.data(), 1);
        scipy_cblas_zgemv(CblasColMajor, CblasNoTrans, n, m, &one, V.ptr(), n, wx.data(), 1, &zero, vw.data(), 1);
        const CVec Mv = apply_M(v);
        if (apply_N) vw = apply_N(vw);
        double r2 = 0.0, size2 = 0.0;
        for (int i = 0; i < n; ++i) {
            r2 += std::norm(Mv[i] - vw[i]);
            size2 += std::norm(Mv[i]);
        }
        if (!(std::sqrt(r2) <= absolute + relative * std::sqrt(size2))) return false;
    }
    return true;
}

std::optional<CVec> symmetric_by_phase(const std::vector<const Mat*>& As, double tolerance) {
    bool symmetric = true;
    for (const Mat* A : As) symmetric = symmetric && is_complex_symmetric(*A, tolerance);
    if (symmetric) return CVec{};
    const Mat& A = *As.front();
    const int n = A.rows;
    if (n < 2) return std::nullopt;
    const cplx a01 = A(0, 1), a10 = A(1, 0);
    double largest = 0.0;
    for (const cplx& a : A.data) largest = std::max(largest, std::abs(a));
    if (!(std::abs(a10) > 1e-8 * largest) || !(std::abs(a01) > 1e-8 * largest)) return std::nullopt;
    cplx u = std::sqrt(a01 / a10);
    if (!(std::abs(std::abs(u) - 1.0) < 1e-6)) return std::nullopt;
    u /= std::abs(u);
    const int M = (n - 1) / 2;
    CVec d(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) d[i] = std::pow(u, i - M);
    for (const Mat* B : As)
        if (!is_complex_symmetric(moved_by_phase(*B, d), tolerance)) return std::nullopt;
    return d;
}

Mat moved_by_phase(const Mat& A, const CVec& d) {
    if (d.empty()) return A;
    Mat out = A;
    for (int j = 0; j < A.cols; ++j) {
        const cplx dj = std::conj(d[j]);
        for (int i = 0; i < A.rows; ++i) out(i, j) = d[i] * A(i, j) * dj;
    }
    return out;
}

std::optional<Mat> symmetric_factor(Mat A) {
    const int n = A.rows;
    double largest = 0.0;
    for (int j = 0; j < n; ++j)
        for (int i = j; i < n; ++i) largest = std::max(largest, std::norm(A(i, j)));
    if (!(largest > 0.0)) return std::nullopt;
    for (int k = 0; k < n; ++k) {
        const cplx pivot = A(k, k);
        if (!(std::norm(pivot) > kEps * kEps * largest)) return std::nullopt;
        const cplx root = std::sqrt(pivot);
        const int m = n - k - 1;
        // Column k of G: A(k+1.., k) / sqrt(pivot); the trailing block loses g g^T (lower).
        A(k, k) = root;
        const cplx inv = 1.0 / root;
        for (int i = k + 1; i < n; ++i) A(i, k) *= inv;
        if (m > 0) {
            const cplx minus_one = -1.0, one = 1.0;
            scipy_cblas_zsyrk(CblasColMajor, CblasLower, CblasNoTrans, m, 1, &minus_one, &A(k + 1, k), n, &one,
                              &A(k + 1, k + 1), n);
        }
    }
    double grown = 0.0;
    for (int j = 0; j < n; ++j)
        for (int i = j; i < n; ++i) grown = std::max(grown, std::norm(A(i, j)));
    if (!(grown <= kComplexSymmetricGrowth * largest)) return std::nullopt;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < j; ++i) A(i, j) = 0.0;
    return A;
}

void triangular_multiply(const Mat& G, Mat& B, char side, char trans) {
    const cplx one = 1.0;
    if (B.rows == 0 || B.cols == 0) return;
    scipy_cblas_ztrmm(CblasColMajor, side == 'L' ? CblasLeft : CblasRight, CblasLower,
                      trans == 'N' ? CblasNoTrans : CblasTrans, CblasNonUnit, B.rows, B.cols, &one, G.ptr(), G.rows,
                      B.ptr(), B.rows);
}

void triangular_solve(const Mat& G, Mat& B, char side, char trans) {
    const cplx one = 1.0;
    if (B.rows == 0 || B.cols == 0) return;
    scipy_cblas_ztrsm(CblasColMajor, side == 'L' ? CblasLeft : CblasRight, CblasLower,
                      trans == 'N' ? CblasNoTrans : CblasTrans, CblasNonUnit, B.rows, B.cols, &one, G.ptr(), G.rows,
                      B.ptr(), B.rows);
}

}  // namespace rcwa
