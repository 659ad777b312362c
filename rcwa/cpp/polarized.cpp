// TE and TM on N x N blocks (polarized.hpp): the enhanced transmittance matrix of
// stack.cpp ([Moharam 1995b, Eqs. 10-15]) and its
// exact closure with the half-spaces, written for one polarization. Every formula is the
// 2N x 2N one of stack.cpp restricted to the nonzero blocks, so the two agree to
// round-off (tests/rcwa/test_fast_paths.py).
#include "polarized.hpp"

#include <cmath>
#include <utility>

namespace rcwa {

namespace {

Mat diagonal_matrix(const CVec& d) {
    Mat out(static_cast<int>(d.size()), static_cast<int>(d.size()));
    for (std::size_t i = 0; i < d.size(); ++i) out(static_cast<int>(i), static_cast<int>(i)) = d[i];
    return out;
}

Mat scale_columns(Mat M, const CVec& d) {
    for (int j = 0; j < M.cols; ++j)
        for (int i = 0; i < M.rows; ++i) M(i, j) *= d[j];
    return M;
}

Mat scale_rows(Mat M, const CVec& d) {
    for (int j = 0; j < M.cols; ++j)
        for (int i = 0; i < M.rows; ++i) M(i, j) *= d[i];
    return M;
}

// sigma_i: s-hat of harmonic i is sigma_i y-hat (stack.cpp, polarization_basis).
std::vector<double> s_signs(const StackProblem& pr) {
    const Harmonics& h = pr.harmonics;
    std::vector<double> sigma(h.size());
    for (int i = 0; i < h.size(); ++i) {
        const double kt = std::hypot(h.kx[i], h.ky[i]);
        sigma[i] = kt > 1e-12 ? h.kx[i] / kt : pr.s_y;
    }
    return sigma;
}

// The superstrate closure rows (stack.cpp, project_up) for one polarization: TE keeps
// kz E_s + h_p = sigma (kz Ey + hx), TM keeps E_p - kz/eps h_s = sigma (Ex - kz/eps hy).
struct Projection {
    CVec on_u, on_v;  // per harmonic: row i is on_u[i] u_i + on_v[i] v_i
};

Projection projection(const StackProblem& pr, const std::vector<double>& sigma, const CVec& kz1, Polarization pol) {
    const int n = pr.harmonics.size();
    Projection p{CVec(n), CVec(n)};
    for (int i = 0; i < n; ++i) {
        if (pol == Polarization::TE) {
            p.on_u[i] = kz1[i] * sigma[i];
            p.on_v[i] = sigma[i];
        } else {
            p.on_u[i] = sigma[i];
            p.on_v[i] = -kz1[i] / pr.eps_superstrate * sigma[i];
        }
    }
    return p;
}

// The substrate's down-going waves (stack.cpp, outgoing_columns), diagonal: TE E = s-hat,
// hx = kz sigma; TM h = s-hat, Ex = -kz/eps sigma. u = f t, v = g t per harmonic.
void substrate_waves(const StackProblem& pr, const std::vector<double>& sigma, const CVec& kz2, Polarization pol,
                     CVec& f, CVec& g) {
    const std::size_t n = sigma.size();
    f.resize(n);
    g.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        f[i] = pol == Polarization::TE ? cplx(sigma[i]) : -kz2[i] / pr.eps_substrate * sigma[i];
        g[i] = pol == Polarization::TE ? kz2[i] * sigma[i] : cplx(sigma[i]);
    }
}

// The incident wave's (u, v) at its harmonic (stack.cpp, close_top): TE E = s-hat,
// hx = kz0 sigma; TM h = s-hat, Ex = -kz0/eps sigma.
std::pair<cplx, cplx> incident_wave(const StackProblem& pr, const std::vector<double>& sigma, const CVec& kz1,
                                    Polarization pol) {
    const int i0 = pr.zero_order;
    const cplx kz0 = kz1[i0];
    if (pol == Polarization::TE) return {cplx(sigma[i0]), kz0 * sigma[i0]};
    return {-kz0 / pr.eps_superstrate * sigma[i0], cplx(sigma[i0])};
}

}  // namespace

Mat Operator::apply(const Mat& B) const { return diag.empty() ? matmul(dense, B) : scale_rows(B, diag); }

Mat Operator::times_diagonal(const CVec& d) const {
    if (diag.empty()) return scale_columns(dense, d);
    CVec product(d.size());
    for (std::size_t i = 0; i < d.size(); ++i) product[i] = diag[i] * d[i];
    return diagonal_matrix(product);
}

Mat Operator::matrix() const { return diag.empty() ? dense : diagonal_matrix(diag); }

PolarizedModes uniform_polarized(const std::vector<double>& kx, cplx eps, Polarization pol) {
    // The blocks of UniformModes (modes.cpp) at ky = 0: W = I; TE: hx = (kx^2 - eps)/kz Ey,
    // inverse -eps/(eps kz); TM: hy = eps/kz Ex, inverse (eps - kx^2)/(eps kz). eps is
    // moved with a regularized kz as there, so that V and V^-1 stay exact inverses.
    const std::size_t n = kx.size();
    PolarizedModes m;
    m.kz.resize(n);
    m.W.diag.assign(n, 1.0);
    m.W_inverse.diag.assign(n, 1.0);
    m.V.diag.resize(n);
    m.V_inverse.diag.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        const double kt2 = kx[i] * kx[i];
        const cplx kz = regularize_kz(outgoing_sqrt(eps - kt2));
        const cplx e = kz * kz + kt2;
        const cplx s = 1.0 / (e * kz);
        m.kz[i] = kz;
        if (pol == Polarization::TE) {
            m.V.diag[i] = (kt2 - e) / kz;
            m.V_inverse.diag[i] = (0.0 - e) * s;
        } else {
            m.V.diag[i] = e / kz;
            m.V_inverse.diag[i] = (e - kt2) * s;
        }
    }
    return m;
}

PolarizedModes lamellar_polarized(const LamellarEigen& e, Polarization pol) {
    // The blocks of LamellarModes (lamellar.cpp) at ky = 0. TE (family A): W = WA,
    // V = -WA muA KzA^-1, W^-1 = WA^-1, V^-1 = -KzA muA^-1 WA^-1. TM (family B):
    // W = B VB KzB^-1, V = VB, W^-1 = KzB (B VB)^-1, V^-1 = VB^-1.
    const std::size_t n = e.kx.size();
    PolarizedModes m;
    m.kz.resize(n);
    if (pol == Polarization::TE) {
        CVec mu_over_kz(n), kz_over_mu(n);
        for (std::size_t i = 0; i < n; ++i) {
            m.kz[i] = layer_kz(e.muA[i]);
            mu_over_kz[i] = -e.muA[i] / m.kz[i];
            kz_over_mu[i] = -m.kz[i] / e.muA[i];
        }
        m.W.dense = e.WA;
        m.V.dense = scale_columns(e.WA, mu_over_kz);
        m.W_inverse.dense = e.WA_inv;
        m.V_inverse.dense = scale_rows(e.WA_inv, kz_over_mu);
    } else {
        CVec inv_kz(n);
        for (std::size_t i = 0; i < n; ++i) {
            m.kz[i] = layer_kz(e.muB[i]);
            inv_kz[i] = 1.0 / m.kz[i];
        }
        m.W.dense = scale_columns(e.B_VB, inv_kz);
        m.V.dense = e.VB;
        m.W_inverse.dense = scale_rows(e.B_VB_inv, m.kz);
        m.V_inverse.dense = e.VB_inv;
    }
    return m;
}

bool decouples(const StackProblem& pr, StackMethod method) {
    if (method != StackMethod::EnhancedTransmittance || pr.thickness.empty()) return false;
    const Harmonics& h = pr.harmonics;
    for (int i = 0; i < h.size(); ++i) {
        if (h.ky[i] != 0.0) return false;
        if (std::abs(h.kx[i]) <= 1e-12 && pr.s_x != 0.0) return false;
    }
    return true;
}

void solve_polarized(const StackProblem& pr, Polarization pol, const std::vector<PolarizedModes>& layers,
                     StackSolution& out) {
    const int n = pr.harmonics.size();
    const int column = pol == Polarization::TE ? 0 : 1;
    const int row0 = pol == Polarization::TE ? 0 : n;  // where this polarization's amplitudes go
    const std::vector<double> sigma = s_signs(pr);
    const CVec& kz1 = out.kz_superstrate;
    const CVec& kz2 = out.kz_substrate;

    CVec f0, g0;
    substrate_waves(pr, sigma, kz2, pol, f0, g0);
    // The bottom layer meets the substrate's diagonal columns (times_diagonal).
    const std::size_t bottom = layers.size() - 1;
    auto inverses = [&](std::size_t k, const Mat& f, const Mat& g) {
        const PolarizedModes& m = layers[k];
        if (k == bottom) return std::make_pair(m.W_inverse.times_diagonal(f0), m.V_inverse.times_diagonal(g0));
        return std::make_pair(m.W_inverse.apply(f), m.V_inverse.apply(g));
    };
    auto forward = [&](std::size_t k, const Mat& P, const Mat& M) {
        return std::make_pair(layers[k].W.apply(P), layers[k].V.apply(M));
    };
    auto kz = [&](std::size_t k) -> const CVec& { return layers[k].kz; };
    EtmSweep sweep = etm_sweep(layers.size(), pr.thickness, Mat(), Mat(), kz, inverses, forward);
    const Mat& R = sweep.R;

    // Close with the superstrate (stack.cpp, close_top_layer): above the top layer the field
    // is [W (I + R); V (R - I)] T; its projection is PW - PV + (PW + PV) R.
    const PolarizedModes& top = layers.front();
    const Projection proj = projection(pr, sigma, kz1, pol);
    const Mat PW = scale_rows(top.W.matrix(), proj.on_u);
    const Mat PV = scale_rows(top.V.matrix(), proj.on_v);
    Mat projected(n, n), sum(n, n);
    for (std::size_t q = 0; q < PW.data.size(); ++q) {
        projected.data[q] = PW.data[q] - PV.data[q];
        sum.data[q] = PW.data[q] + PV.data[q];
    }
    gemm(sum, R, projected, 1.0, 1.0);
    const int i0 = pr.zero_order;
    const auto [u_inc, v_inc] = incident_wave(pr, sigma, kz1, pol);
    Mat T(n, 1);
    T(i0, 0) = proj.on_u[i0] * u_inc + proj.on_v[i0] * v_inc;
    T = LU(std::move(projected)).solve(T);
    const Mat RT = matmul(R, T);
    Mat plus = RT, minus = RT;
    for (int i = 0; i < n; ++i) {
        plus(i, 0) += T(i, 0);
        minus(i, 0) -= T(i, 0);
    }
    const Mat u = top.W.apply(plus), v = top.V.apply(minus);
    for (int i = 0; i < n; ++i) {
        // r: TE by E along s-hat (sigma Ey), TM by h along s-hat (sigma hy).
        const cplx field = pol == Polarization::TE ? u(i, 0) - (i == i0 ? u_inc : 0.0) : v(i, 0) - (i == i0 ? v_inc : 0.0);
        out.r(row0 + i, column) = sigma[i] * field;
    }
    etm_walk_down(sweep.steps, T);
    for (int i = 0; i < n; ++i) out.t(row0 + i, column) = T(i, 0);
}

void solve_polarized_direct(const StackProblem& pr, Polarization pol, const PolarizedModes& layer, StackSolution& out) {
    // One layer of thickness d between the half-spaces ([Moharam 1995a, Eqs. 11-15] (TE) and
    // [Moharam 1995a, Eqs. 30-34] (TM): the tangential fields matched
    // at both interfaces). In the layer u = W (phi1 c1 + phi2 c2), v = V (-phi1 c1 + phi2 c2),
    // with phi1 = I at the top and X at the bottom, phi2 = X at the top and I at the bottom
    // (X = exp(i kz k0 d): both families decay away from where their amplitudes are given,
    // as in the ETM sweep, whose T is c1 and whose R T is X c2). Unknowns c1, c2:
    //   top, the superstrate's projection (which annihilates its up-going waves) of the field
    //   equals that of the incident wave: (PW - PV) c1 + (PW + PV) X c2 = p_inc;
    //   bottom, only down-going substrate waves (u, v) = (f0, g0) t: the rows g0 u - f0 v
    //   vanish: (G W + F V) X c1 + (G W - F V) c2 = 0.
    // Then r from the top field and t from the bottom one.
    const int n = pr.harmonics.size();
    const int column = pol == Polarization::TE ? 0 : 1;
    const int row0 = pol == Polarization::TE ? 0 : n;
    const std::vector<double> sigma = s_signs(pr);
    const CVec& kz1 = out.kz_superstrate;
    const CVec& kz2 = out.kz_substrate;
    CVec f0, g0;
    substrate_waves(pr, sigma, kz2, pol, f0, g0);
    const Projection proj = projection(pr, sigma, kz1, pol);
    const Mat W = layer.W.matrix(), V = layer.V.matrix();
    CVec X(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) X[i] = std::exp(cplx(0.0, 1.0) * layer.kz[i] * pr.thickness.front());
    Mat M(2 * n, 2 * n);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const cplx pw = proj.on_u[i] * W(i, j), pv = proj.on_v[i] * V(i, j);
            const cplx gw = g0[i] * W(i, j), fv = f0[i] * V(i, j);
            M(i, j) = pw - pv;
            M(i, n + j) = (pw + pv) * X[j];
            M(n + i, j) = (gw + fv) * X[j];
            M(n + i, n + j) = gw - fv;
        }
    const int i0 = pr.zero_order;
    const auto [u_inc, v_inc] = incident_wave(pr, sigma, kz1, pol);
    Mat rhs(2 * n, 1);
    rhs(i0, 0) = proj.on_u[i0] * u_inc + proj.on_v[i0] * v_inc;
    const Mat c = LU(std::move(M)).solve(rhs);
    Mat top_sum(n, 1), top_diff(n, 1), bottom_sum(n, 1), bottom_diff(n, 1);
    for (int j = 0; j < n; ++j) {
        const cplx c1 = c(j, 0), c2 = c(n + j, 0);
        top_sum(j, 0) = c1 + X[j] * c2;       // u = W (c1 + X c2) at the top
        top_diff(j, 0) = X[j] * c2 - c1;      // v = V (X c2 - c1)
        bottom_sum(j, 0) = X[j] * c1 + c2;    // u = W (X c1 + c2) at the bottom
        bottom_diff(j, 0) = c2 - X[j] * c1;   // v = V (c2 - X c1)
    }
    const Mat u_top = matmul(W, top_sum), v_top = matmul(V, top_diff);
    const Mat u_bottom = matmul(W, bottom_sum), v_bottom = matmul(V, bottom_diff);
    for (int i = 0; i < n; ++i) {
        const cplx field = pol == Polarization::TE ? u_top(i, 0) - (i == i0 ? u_inc : 0.0)
                                                   : v_top(i, 0) - (i == i0 ? v_inc : 0.0);
        out.r(row0 + i, column) = sigma[i] * field;
        // t from both components (least squares over (f0, g0) t = (u, v): exact where the
        // system is, and defined where one of f0, g0 vanishes, as TM's f0 at a Rayleigh point).
        out.t(row0 + i, column) = (std::conj(f0[i]) * u_bottom(i, 0) + std::conj(g0[i]) * v_bottom(i, 0)) /
                                  (std::norm(f0[i]) + std::norm(g0[i]));
    }
}

}  // namespace rcwa
