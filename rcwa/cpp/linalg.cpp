#include "linalg.hpp"

#include <algorithm>
#include <cmath>
#include <string>

// LAPACKE's complex type is std::complex<double> here, so no casts are needed.
#define lapack_complex_float std::complex<float>
#define lapack_complex_double std::complex<double>
#include "cblas.h"
#include "lapacke.h"

namespace rcwa {

Mat Mat::identity(int n) {
    Mat I(n, n);
    for (int i = 0; i < n; ++i) I(i, i) = 1.0;
    return I;
}

void gemm(const Mat& A, const Mat& B, Mat& C, cplx alpha, cplx beta, char transA, char transB) {
    const int m = transA == 'N' ? A.rows : A.cols;
    const int k = transA == 'N' ? A.cols : A.rows;
    const int n = transB == 'N' ? B.cols : B.rows;
    if ((transB == 'N' ? B.rows : B.cols) != k || C.rows != m || C.cols != n)
        throw std::invalid_argument("gemm: shape mismatch");
    if (m == 0 || n == 0) return;
    scipy_cblas_zgemm(CblasColMajor, transA == 'N' ? CblasNoTrans : CblasTrans,
                      transB == 'N' ? CblasNoTrans : CblasTrans, m, n, k, &alpha, A.ptr(),
                      A.rows > 0 ? A.rows : 1, B.ptr(), B.rows > 0 ? B.rows : 1, &beta, C.ptr(),
                      C.rows > 0 ? C.rows : 1);
}

void gemm_block(int m, int n, int k, cplx alpha, const cplx* A, int lda, const cplx* B, int ldb, cplx beta, cplx* C,
                int ldc) {
    if (m == 0 || n == 0) return;
    scipy_cblas_zgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, m, n, k, &alpha, A, std::max(1, lda), B,
                      std::max(1, ldb), &beta, C, std::max(1, ldc));
}

Mat matmul(const Mat& A, const Mat& B) {
    Mat C(A.rows, B.cols);
    gemm(A, B, C);
    return C;
}

LU::LU(Mat A) : lu_(std::move(A)), ipiv_(static_cast<std::size_t>(lu_.rows)) {
    if (lu_.rows != lu_.cols) throw std::invalid_argument("LU: matrix is not square");
    int n = lu_.rows, info = 0;
    if (n == 0) return;
    info = scipy_LAPACKE_zgetrf_work(LAPACK_COL_MAJOR, n, n, lu_.ptr(), n, ipiv_.data());
    if (info > 0) throw std::runtime_error("LU: matrix is exactly singular");
    if (info < 0) throw std::runtime_error("LU: zgetrf argument error");
}

Mat LU::solve(const Mat& B) const {
    Mat X = B;
    int n = lu_.rows, nrhs = B.cols, info = 0;
    if (n == 0 || nrhs == 0) return X;
    info = scipy_LAPACKE_zgetrs_work(LAPACK_COL_MAJOR, 'N', n, nrhs, lu_.ptr(), n, ipiv_.data(),
                                     X.ptr(), n);
    if (info != 0) throw std::runtime_error("LU::solve: zgetrs failed");
    return X;
}

Mat LU::solve_right(const Mat& B) const {
    // X A = B with A = P L U (zgetrf): X P L U = B, so Y = X P solves Y L U = B by two
    // triangular solves from the right (ztrsm; zgetrs on the transposed system, with two
    // transposing copies, took 118 us against 99 at n = 61), and X = Y P^T undoes the row
    // interchanges as column interchanges, last first.
    const int n = lu_.rows;
    if (B.cols != n) throw std::invalid_argument("LU::solve_right: shape mismatch");
    Mat X = B;
    if (n == 0 || B.rows == 0) return X;
    const cplx one(1.0, 0.0);
    scipy_cblas_ztrsm(CblasColMajor, CblasRight, CblasUpper, CblasNoTrans, CblasNonUnit, X.rows, n, &one, lu_.ptr(), n,
                      X.ptr(), X.rows);
    scipy_cblas_ztrsm(CblasColMajor, CblasRight, CblasLower, CblasNoTrans, CblasUnit, X.rows, n, &one, lu_.ptr(), n,
                      X.ptr(), X.rows);
    for (int k = n - 1; k >= 0; --k) {
        const int p = ipiv_[static_cast<std::size_t>(k)] - 1;  // zgetrf's pivots are 1-based
        if (p != k) std::swap_ranges(&X(0, k), &X(0, k) + X.rows, &X(0, p));
    }
    return X;
}

Mat LU::inverse() const {
    // zgetri from the factors: two thirds of the work of solving with the identity (zgetrs).
    Mat X = lu_;
    const int n = lu_.rows;
    if (n == 0) return X;
    cplx query;
    int info = scipy_LAPACKE_zgetri_work(LAPACK_COL_MAJOR, n, X.ptr(), n, ipiv_.data(), &query, -1);
    if (info != 0) throw std::runtime_error("LU::inverse: zgetri workspace query failed");
    std::vector<cplx> work(static_cast<std::size_t>(std::max(1, static_cast<int>(query.real()))));
    info = scipy_LAPACKE_zgetri_work(LAPACK_COL_MAJOR, n, X.ptr(), n, ipiv_.data(), work.data(),
                                     static_cast<int>(work.size()));
    if (info != 0) throw std::runtime_error("LU::inverse: zgetri failed");
    return X;
}

Eigen eig(Mat A) {
    if (A.rows != A.cols) throw std::invalid_argument("eig: matrix is not square");
    const int n = A.rows;
    Eigen out;
    out.values.assign(static_cast<std::size_t>(n), 0.0);
    out.vectors = Mat(n, n);
    if (n == 0) return out;
    std::vector<double> rwork(2 * static_cast<std::size_t>(n));
    cplx query, dummy;
    int info = scipy_LAPACKE_zgeev_work(LAPACK_COL_MAJOR, 'N', 'V', n, A.ptr(), n,
                                        out.values.data(), &dummy, 1, out.vectors.ptr(), n,
                                        &query, -1, rwork.data());
    const int lwork = static_cast<int>(query.real());
    CVec work(static_cast<std::size_t>(lwork));
    info = scipy_LAPACKE_zgeev_work(LAPACK_COL_MAJOR, 'N', 'V', n, A.ptr(), n, out.values.data(),
                                    &dummy, 1, out.vectors.ptr(), n, work.data(), lwork,
                                    rwork.data());
    if (info != 0)
        throw std::runtime_error("eig: zgeev did not converge (info=" + std::to_string(info) + ")");
    return out;
}

std::optional<Eigen> eig_small(Mat A) {
    if (A.rows != A.cols) throw std::invalid_argument("eig_small: matrix is not square");
    const int n = A.rows;
    if (n == 0 || n >= kInverseIterationMax) return std::nullopt;
    int ilo = 1, ihi = n;
    std::vector<double> scale(static_cast<std::size_t>(n), 1.0);
    if (scipy_LAPACKE_zgebal_work(LAPACK_COL_MAJOR, 'B', n, A.ptr(), n, &ilo, &ihi, scale.data()) != 0)
        return std::nullopt;
    CVec tau(static_cast<std::size_t>(std::max(1, n - 1)));
    CVec work(static_cast<std::size_t>(n) * n);  // enough for zgehrd, zhseqr, zhsein and zunmhr at n < 75
    const int lwork = static_cast<int>(work.size());
    if (scipy_LAPACKE_zgehrd_work(LAPACK_COL_MAJOR, n, ilo, ihi, A.ptr(), n, tau.data(), work.data(), lwork) != 0)
        return std::nullopt;
    Mat H = A;  // the Hessenberg matrix (A keeps the reflectors below its subdiagonal)
    for (int j = 0; j < n; ++j)
        for (int i = j + 2; i < n; ++i) H(i, j) = 0.0;
    Mat T = H;
    Eigen out;
    out.values.resize(static_cast<std::size_t>(n));
    if (scipy_LAPACKE_zhseqr_work(LAPACK_COL_MAJOR, 'E', 'N', n, ilo, ihi, T.ptr(), n, out.values.data(), nullptr, 1,
                                  work.data(), lwork) != 0)
        return std::nullopt;
    CVec w = out.values;  // zhsein may perturb close eigenvalues; the returned ones are zhseqr's
    std::vector<int> select(static_cast<std::size_t>(n), 1), ifaill(static_cast<std::size_t>(n)),
        ifailr(static_cast<std::size_t>(n));
    std::vector<double> rwork(static_cast<std::size_t>(n));
    out.vectors = Mat(n, n);
    int found = 0;
    cplx none;
    const int info = scipy_LAPACKE_zhsein_work(LAPACK_COL_MAJOR, 'R', 'Q', 'N', select.data(), n, H.ptr(), n, w.data(),
                                               &none, 1, out.vectors.ptr(), n, n, &found, work.data(), rwork.data(),
                                               ifaill.data(), ifailr.data());
    if (info != 0 || found != n) return std::nullopt;
    if (scipy_LAPACKE_zunmhr_work(LAPACK_COL_MAJOR, 'L', 'N', n, n, ilo, ihi, A.ptr(), n, tau.data(),
                                  out.vectors.ptr(), n, work.data(), lwork) != 0)
        return std::nullopt;
    if (scipy_LAPACKE_zgebak_work(LAPACK_COL_MAJOR, 'B', 'R', n, ilo, ihi, scale.data(), n, out.vectors.ptr(), n) != 0)
        return std::nullopt;
    for (int j = 0; j < n; ++j) {  // unit 2-norm, as zgeev's
        double norm2 = 0.0;
        for (int i = 0; i < n; ++i) norm2 += std::norm(out.vectors(i, j));
        const double inv = 1.0 / std::sqrt(norm2);
        for (int i = 0; i < n; ++i) out.vectors(i, j) *= inv;
    }
    return out;
}

bool is_hermitian(const Mat& A, double tolerance) {
    if (A.rows != A.cols) return false;
    // Squared moduli (std::norm): std::abs takes a hypot per entry, which made these checks
    // a tenth of a lossless 1D solve at N = 61.
    double largest = 0.0, asymmetry = 0.0;
    for (int j = 0; j < A.cols; ++j)
        for (int i = 0; i <= j; ++i) {
            largest = std::max(largest, std::max(std::norm(A(i, j)), std::norm(A(j, i))));
            asymmetry = std::max(asymmetry, std::norm(A(i, j) - std::conj(A(j, i))));
        }
    return asymmetry <= tolerance * tolerance * largest;
}

Eigen eig_hermitian(Mat A) {
    if (A.rows != A.cols) throw std::invalid_argument("eig_hermitian: matrix is not square");
    const int n = A.rows;
    std::vector<double> w(static_cast<std::size_t>(n));
    Eigen out;
    if (n > 0) {
        const int info = scipy_LAPACKE_zheevd(LAPACK_COL_MAJOR, 'V', 'L', n, A.ptr(), n, w.data());
        if (info != 0) throw std::runtime_error("eig_hermitian: zheevd failed (info=" + std::to_string(info) + ")");
    }
    out.values.assign(w.begin(), w.end());
    out.vectors = std::move(A);
    return out;
}

std::optional<Eigen> eig_hermitian_definite(Mat A, Mat B) {
    if (A.rows != A.cols || B.rows != A.rows || B.cols != A.cols)
        throw std::invalid_argument("eig_hermitian_definite: shape mismatch");
    const int n = A.rows;
    std::vector<double> w(static_cast<std::size_t>(n));
    if (n > 0) {
        const int info = scipy_LAPACKE_zhegvd(LAPACK_COL_MAJOR, 1, 'V', 'L', n, A.ptr(), n, B.ptr(), n, w.data());
        if (info > n) return std::nullopt;  // B is not positive definite
        if (info != 0)
            throw std::runtime_error("eig_hermitian_definite: zhegvd failed (info=" + std::to_string(info) + ")");
    }
    Eigen out;
    out.values.assign(w.begin(), w.end());
    out.vectors = std::move(A);
    return out;
}

Mat adjoint(const Mat& A) {
    Mat out(A.cols, A.rows);
    for (int j = 0; j < A.cols; ++j)
        for (int i = 0; i < A.rows; ++i) out(j, i) = std::conj(A(i, j));
    return out;
}

RMat matmul(const RMat& A, const RMat& B) {
    if (A.cols != B.rows) throw std::invalid_argument("matmul: shape mismatch");
    RMat C(A.rows, B.cols);
    if (A.rows == 0 || B.cols == 0) return C;
    scipy_cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, A.rows, B.cols, A.cols, 1.0, A.data.data(),
                      A.rows > 0 ? A.rows : 1, B.data.data(), B.rows > 0 ? B.rows : 1, 0.0, C.data.data(),
                      C.rows > 0 ? C.rows : 1);
    return C;
}

std::optional<RealForm> real_by_phase(const std::vector<const Mat*>& As, double tolerance) {
    if (As.empty() || As[0]->rows < 2 || As[0]->rows % 2 == 0) return std::nullopt;
    const Mat& A0 = *As[0];
    const int n = A0.rows, half = n / 2;
    double largest = 0.0;
    for (const cplx& v : A0.data) largest = std::max(largest, std::norm(v));
    largest = std::sqrt(largest);
    const cplx a01 = A0(0, 1);
    if (!(std::abs(a01) > 1e-8 * largest)) return std::nullopt;
    const cplx u = a01 / std::abs(a01);
    RealForm out;
    out.d.resize(static_cast<std::size_t>(n));
    out.d[half] = 1.0;
    for (int i = half + 1; i < n; ++i) out.d[i] = out.d[i - 1] * u;
    for (int i = half - 1; i >= 0; --i) out.d[i] = out.d[i + 1] * std::conj(u);
    for (const Mat* A : As) {
        if (A->rows != n || A->cols != n) return std::nullopt;
        double top = 0.0;
        for (const cplx& v : A->data) top = std::max(top, std::norm(v));
        top = std::sqrt(top);
        RMat R(n, n);
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const cplx v = out.d[i] * (*A)(i, j) * std::conj(out.d[j]);
                if (std::abs(v.imag()) > tolerance * top) return std::nullopt;
                R(i, j) = v.real();
            }
        out.real.push_back(std::move(R));
    }
    return out;
}

RealEigen eig_symmetric(RMat A) {
    if (A.rows != A.cols) throw std::invalid_argument("eig_symmetric: matrix is not square");
    const int n = A.rows;
    RealEigen out;
    out.values.resize(static_cast<std::size_t>(n));
    if (n > 0) {
        const int info = scipy_LAPACKE_dsyevd(LAPACK_COL_MAJOR, 'V', 'L', n, A.data.data(), n, out.values.data());
        if (info != 0) throw std::runtime_error("eig_symmetric: dsyevd failed (info=" + std::to_string(info) + ")");
    }
    out.vectors = std::move(A);
    return out;
}

std::optional<RealEigen> eig_symmetric_definite(RMat A, RMat B) {
    if (A.rows != A.cols || B.rows != A.rows || B.cols != A.cols)
        throw std::invalid_argument("eig_symmetric_definite: shape mismatch");
    const int n = A.rows;
    RealEigen out;
    out.values.resize(static_cast<std::size_t>(n));
    if (n > 0) {
        const int info = scipy_LAPACKE_dsygvd(LAPACK_COL_MAJOR, 1, 'V', 'L', n, A.data.data(), n, B.data.data(), n,
                                              out.values.data());
        if (info > n) return std::nullopt;  // B is not positive definite
        if (info != 0)
            throw std::runtime_error("eig_symmetric_definite: dsygvd failed (info=" + std::to_string(info) + ")");
    }
    out.vectors = std::move(A);
    return out;
}

namespace {

void normalize_columns(Mat& W) {
    for (int j = 0; j < W.cols; ++j) {
        double norm2 = 0.0;
        for (int i = 0; i < W.rows; ++i) norm2 += std::norm(W(i, j));
        const double scale = 1.0 / std::sqrt(norm2);
        for (int i = 0; i < W.rows; ++i) W(i, j) *= scale;
    }
}

}  // namespace

std::optional<Eigen> eig_from_guess(const Mat& A, const Mat& guess, int max_steps) {
    // A correction below kConverged leaves an error of its square; a step that no longer
    // shrinks a correction below kFloor has reached round-off (a close pair of eigenvalues).
    constexpr double kConverged = 1e-9, kFloor = 1e-7, kTooFar = 0.25;
    const int n = A.rows;
    if (guess.rows != n || guess.cols != n) throw std::invalid_argument("eig_from_guess: shape mismatch");
    Eigen out;
    out.vectors = guess;
    normalize_columns(out.vectors);
    out.values.resize(static_cast<std::size_t>(n));
    double previous = kTooFar;
    for (int step = 0; step < max_steps; ++step) {
        Mat M;
        try {
            M = LU(out.vectors).solve(matmul(A, out.vectors));
        } catch (const std::runtime_error&) {
            return std::nullopt;  // the guess lost rank
        }
        for (int i = 0; i < n; ++i) out.values[i] = M(i, i);
        Mat P(n, n);
        double largest2 = 0.0;  // squared magnitudes: no hypot, and no __divdc3, in the loop
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                if (i == j) continue;
                const cplx gap = out.values[j] - out.values[i];
                const double gap2 = std::norm(gap);
                if (gap2 == 0.0) return std::nullopt;
                P(i, j) = M(i, j) * std::conj(gap) / gap2;
                const double size2 = std::norm(P(i, j));
                if (!(size2 <= largest2)) largest2 = size2;  // NaN sticks
            }
        const double largest = std::sqrt(largest2);
        if (!(largest <= kTooFar)) return std::nullopt;  // too far, or NaN
        Mat W = out.vectors;
        gemm(out.vectors, P, W, 1.0, 1.0);  // W (I + P)
        out.vectors = std::move(W);
        normalize_columns(out.vectors);
        if (largest <= kConverged || (largest <= kFloor && largest > 0.1 * previous)) return out;
        previous = largest;
    }
    return std::nullopt;
}

void set_blas_threads(int n) { scipy_openblas_set_num_threads(n); }

}  // namespace rcwa
