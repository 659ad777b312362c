#include "linalg.hpp"

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
    // X A = B  <=>  A^T X^T = B^T.
    const int n = lu_.rows;
    Mat Bt(B.cols, B.rows);
    for (int j = 0; j < B.cols; ++j)
        for (int i = 0; i < B.rows; ++i) Bt(j, i) = B(i, j);
    int nrhs = B.rows, info = 0, nn = n;
    if (n == 0 || nrhs == 0) return B;
    info = scipy_LAPACKE_zgetrs_work(LAPACK_COL_MAJOR, 'T', nn, nrhs, lu_.ptr(), nn, ipiv_.data(),
                                     Bt.ptr(), nn);
    if (info != 0) throw std::runtime_error("LU::solve_right: zgetrs failed");
    Mat X(B.rows, B.cols);
    for (int j = 0; j < B.cols; ++j)
        for (int i = 0; i < B.rows; ++i) X(i, j) = Bt(j, i);
    return X;
}

Mat LU::inverse() const { return solve(Mat::identity(lu_.rows)); }

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

void set_blas_threads(int n) { scipy_openblas_set_num_threads(n); }

}  // namespace rcwa
