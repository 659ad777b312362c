// Modes of a 1D lamellar layer in conical incidence from two N x N eigen-solves.
//
// With Ky = ky I (one ky for every harmonic) and Z = E^{-1}, the matrix P Q of modes.hpp
// is block lower-triangular,
//     P Q = [[MB' - ky^2, 0], [., MA - ky^2]],   MA = E - Kx^2,
// and Q P = [[MA - ky^2, 0], [., MB - ky^2]],   MB = Exx (I - Kx Z Kx),
// (MB' = (I - Kx Z Kx) Exx is similar to MB). So one family of modes has Ex = 0 (pure Ey,
// eigenvectors WA of MA: TE-like) and the other has hx = 0 (pure hy, eigenvectors VB of
// MB: TM-like); kz^2 = mu - ky^2 for both. This is the decoupling of Moharam, Grann,
// Pommet & Gaylord 1995 (JOSA A 12, 1068, Eqs. 40-49, conical diffraction) written for
// Li's inverse rule (Li 1996, JOSA A 13, 1870, Eq. 37: Exx = [[1/eps]]^{-1}). The
// eigenvectors do not depend on ky; only kz and the assembly below do.
//   family A:  psi = [0; WA],                      phi = [-WA muA; ky Kx WA] / kzA
//   family B:  psi = [(I - Kx Z Kx) VB; -ky Z Kx VB] / kzB,  phi = [0; VB]
#include "modes.hpp"

namespace rcwa {

LamellarEigen lamellar_eigen(const std::vector<double>& kx, const Mat& E, const Mat& Exx) {
    const int n = static_cast<int>(kx.size());
    LamellarEigen out;
    Mat MA = E;
    for (int i = 0; i < n; ++i) MA(i, i) -= kx[i] * kx[i];
    Eigen ea = eig(std::move(MA));
    out.WA = std::move(ea.vectors);
    out.muA = std::move(ea.values);

    out.Z = LU(E).inverse();
    Mat Bm(n, n);  // I - Kx Z Kx
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) Bm(i, j) = (i == j ? 1.0 : 0.0) - kx[i] * out.Z(i, j) * kx[j];
    Eigen eb = eig(matmul(Exx, Bm));
    out.VB = std::move(eb.vectors);
    out.muB = std::move(eb.values);

    out.B_VB = matmul(Bm, out.VB);
    Mat KxVB = out.VB;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) KxVB(i, j) *= kx[i];
    out.ZKx_VB = matmul(out.Z, KxVB);
    return out;
}

std::unique_ptr<LayerModes> lamellar_modes(const std::vector<double>& kx, const LamellarEigen& e,
                                           double ky) {
    const int n = static_cast<int>(kx.size());
    CVec kz(2 * static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
        kz[i] = regularize_kz(outgoing_sqrt(e.muA[i] - ky * ky));
        kz[n + i] = regularize_kz(outgoing_sqrt(e.muB[i] - ky * ky));
    }
    Mat W(2 * n, 2 * n), V(2 * n, 2 * n);
    for (int j = 0; j < n; ++j) {
        const cplx kzA = kz[j], kzB = kz[n + j];
        for (int i = 0; i < n; ++i) {
            W(n + i, j) = e.WA(i, j);
            W(i, n + j) = e.B_VB(i, j) / kzB;
            W(n + i, n + j) = -ky * e.ZKx_VB(i, j) / kzB;
            V(i, j) = -e.WA(i, j) * e.muA[j] / kzA;
            V(n + i, j) = ky * kx[i] * e.WA(i, j) / kzA;
            V(n + i, n + j) = e.VB(i, j);
        }
    }
    return std::make_unique<DenseModes>(std::move(W), std::move(V), std::move(kz));
}

}  // namespace rcwa
