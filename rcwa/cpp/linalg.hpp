// Dense complex linear algebra on column-major matrices, over LAPACK/BLAS from
// scipy-openblas32 (symbols prefixed scipy_). The core has no Python in it.
#pragma once

#include <complex>
#include <cstddef>
#include <optional>
#include <stdexcept>
#include <vector>

namespace rcwa {

using cplx = std::complex<double>;
using CVec = std::vector<cplx>;

// A dense column-major complex matrix.
struct Mat {
    int rows = 0;
    int cols = 0;
    CVec data;

    Mat() = default;
    Mat(int r, int c) : rows(r), cols(c), data(static_cast<std::size_t>(r) * c, cplx(0.0, 0.0)) {}

    cplx& operator()(int i, int j) { return data[static_cast<std::size_t>(j) * rows + i]; }
    const cplx& operator()(int i, int j) const { return data[static_cast<std::size_t>(j) * rows + i]; }
    cplx* ptr() { return data.data(); }
    const cplx* ptr() const { return data.data(); }

    static Mat identity(int n);
};

// C = alpha * op(A) * op(B) + beta * C, op = 'N' (none) or 'T' (transpose).
void gemm(const Mat& A, const Mat& B, Mat& C, cplx alpha = 1.0, cplx beta = 0.0,
          char transA = 'N', char transB = 'N');
Mat matmul(const Mat& A, const Mat& B);
// C = alpha * A * B + beta * C on column-major blocks given by their first entry and leading
// dimension (m x k times k x n), such as the halves of a 2N x 2N matrix, without copying them.
void gemm_block(int m, int n, int k, cplx alpha, const cplx* A, int lda, const cplx* B, int ldb, cplx beta, cplx* C,
                int ldc);

// LU factorization of a square matrix, kept for repeated solves.
class LU {
  public:
    explicit LU(Mat A);  // throws std::runtime_error if singular
    Mat solve(const Mat& B) const;            // A^{-1} B
    Mat solve_right(const Mat& B) const;      // B A^{-1}
    Mat inverse() const;
    int n() const { return lu_.rows; }

  private:
    Mat lu_;
    std::vector<int> ipiv_;
};

// Eigen-decomposition of a general square matrix: A V = V diag(w). Right vectors only.
struct Eigen {
    CVec values;
    Mat vectors;
};
Eigen eig(Mat A);
// The same decomposition for small matrices (below kInverseIterationMax): balanced
// Hessenberg reduction (zgebal, zgehrd), the eigenvalues alone by the QR algorithm (zhseqr
// without Schur vectors: about half of zgeev's time), the eigenvectors by inverse
// iteration on the Hessenberg matrix (zhsein, O(n^2) each) and back-transformed (zunmhr,
// zgebak), columns normalized as zgeev's. 20 % faster than zgeev at n = 61, where zhseqr
// runs its unblocked kernel; slower above (zgeev's blocked kernels). Nothing (use eig)
// at n >= kInverseIterationMax or where inverse iteration does not converge for some
// eigenvector. Its eigenvectors' residuals are ~1e-14 relative against zgeev's ~4e-15.
constexpr int kInverseIterationMax = 75;
std::optional<Eigen> eig_small(Mat A);

// Whether A equals its conjugate transpose to `tolerance` relative to its largest entry.
bool is_hermitian(const Mat& A, double tolerance);
// Eigen-decomposition of a Hermitian matrix (lower triangle read; LAPACK zheevd,
// divide and conquer): A = V diag(w) V^H, w real, V unitary.
Eigen eig_hermitian(Mat A);
// The Hermitian-definite pencil A v = w B v (lower triangles read; LAPACK zhegvd with
// itype 1): w real, V^H B V = I. Nothing when B is not positive definite (its Cholesky
// factorization fails).
std::optional<Eigen> eig_hermitian_definite(Mat A, Mat B);
// The conjugate transpose.
Mat adjoint(const Mat& A);

// A dense column-major real matrix (the real-arithmetic eigen-solves below).
struct RMat {
    int rows = 0;
    int cols = 0;
    std::vector<double> data;

    RMat() = default;
    RMat(int r, int c) : rows(r), cols(c), data(static_cast<std::size_t>(r) * c, 0.0) {}
    double& operator()(int i, int j) { return data[static_cast<std::size_t>(j) * rows + i]; }
    double operator()(int i, int j) const { return data[static_cast<std::size_t>(j) * rows + i]; }
};
RMat matmul(const RMat& A, const RMat& B);
// A diagonal unitary D = diag(d) that makes the Hermitian Toeplitz-like matrices `As` real
// together, D A D^H real to `tolerance` relative to each one's largest entry, and those
// real matrices; nothing when there is none. With harmonics ordered m = -M..M (row i has
// m_i = i - M) a layer whose profile is even about some x0 has Fourier matrices
// A_ij = r(m_j - m_i) exp(-i (m_j - m_i) g x0) with r real and even, so d_i = u^(m_i),
// u = A_01 / |A_01| (up to a sign, which keeps D A D^H real): moving the origin to x0.
struct RealForm {
    CVec d;
    std::vector<RMat> real;
};
std::optional<RealForm> real_by_phase(const std::vector<const Mat*>& As, double tolerance);
// Eigen-decomposition of a real symmetric matrix (LAPACK dsyevd, lower triangle):
// A = V diag(w) V^T, V orthogonal.
struct RealEigen {
    std::vector<double> values;
    RMat vectors;
};
RealEigen eig_symmetric(RMat A);
// The symmetric-definite pencil A v = w B v (LAPACK dsygvd, itype 1): V^T B V = I.
// Nothing when B is not positive definite.
std::optional<RealEigen> eig_symmetric_definite(RMat A, RMat B);

// The eigen-decomposition of A refined from approximate eigenvectors `guess` (columns),
// such as those of a neighbouring matrix in a sweep, by Newton's iteration on the
// decomposition: with M = W^-1 A W (nearly diagonal), each step replaces W by W (I + P),
// P_ij = M_ij / (M_jj - M_ii) for i != j, the first-order correction of perturbation
// theory ([Stewart 1990, Sec. V.2]; the simultaneous form of the refinement of
// [Dongarra 1983]). Convergence is quadratic while the corrections are small. Returns nothing when
// the guess does not separate the eigenvalues (a correction above 1/4: near-degenerate
// or crossing eigenvalues) or it does not converge in `max_steps`: use eig() then.
std::optional<Eigen> eig_from_guess(const Mat& A, const Mat& guess, int max_steps = 6);

void set_blas_threads(int n);

}  // namespace rcwa
