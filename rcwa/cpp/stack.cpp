// Two stack methods over the PQ modes of modes.hpp; neither ever forms a growing
// exponential (only X = e^{i kz d}, |X| <= 1, appears), so thick and lossy layers stay
// stable:
// * scattering matrices: each layer's S-matrix in a fictitious gap medium (zero thickness
//   between every two layers), combined by the Redheffer star product ([Rumpf 2011,
//   Eqs. 60-73]). The gap medium is lossless with eps_gap = 1 + max kt^2, so
//   every order propagates in it with kz >= 1: its basis never degenerates.
// * enhanced transmittance matrix ([Moharam 1995b, Eqs. 10-15]): the stack walked once
//   from the substrate up.
//
// The half-spaces enter only through their outgoing waves, as tall 4N x 2N matrices whose
// columns stay independent at kz = 0 (s waves normalized by E, p waves by h): an order
// grazing the superstrate or substrate (a Rayleigh anomaly) is solved exactly, without
// dividing by kz. At the top, a 2N x 4N projection that annihilates the reflected waves
// (rows kz E_s + h_p and E_p - kz/eps h_s per order) gives a 2N x 2N system.
#include "stack.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <utility>

namespace rcwa {

Basis polarization_basis(const StackProblem& pr) {
    const int n = pr.harmonics.size();
    Basis b;
    b.sx.resize(n);
    b.sy.resize(n);
    b.px.resize(n);
    b.py.resize(n);
    for (int i = 0; i < n; ++i) {
        const double kx = pr.harmonics.kx[i], ky = pr.harmonics.ky[i];
        const double kt = std::hypot(kx, ky);
        if (kt > 1e-12) {
            b.sx[i] = -ky / kt;
            b.sy[i] = kx / kt;
        } else {
            b.sx[i] = pr.s_x;
            b.sy[i] = pr.s_y;
        }
        b.px[i] = b.sy[i];
        b.py[i] = -b.sx[i];
    }
    return b;
}

void outgoing_columns(const Basis& b, const CVec& kz, cplx eps, double direction, Mat& F, Mat& G) {
    const int n = static_cast<int>(kz.size());
    F = Mat(2 * n, 2 * n);
    G = Mat(2 * n, 2 * n);
    for (int i = 0; i < n; ++i) {
        // s: E = s-hat, h_t = -direction * kz p-hat.
        F(i, i) = b.sx[i];
        F(n + i, i) = b.sy[i];
        G(i, i) = -direction * kz[i] * b.px[i];
        G(n + i, i) = -direction * kz[i] * b.py[i];
        // p: h = s-hat, E_t = direction * kz / eps p-hat.
        const cplx e = direction * kz[i] / eps;
        F(i, n + i) = e * b.px[i];
        F(n + i, n + i) = e * b.py[i];
        G(i, n + i) = b.sx[i];
        G(n + i, n + i) = b.sy[i];
    }
}

namespace {

CVec propagation(const LayerModes& m, double k0d) {
    CVec X(m.kz().size());
    for (std::size_t i = 0; i < X.size(); ++i) X[i] = std::exp(cplx(0.0, 1.0) * m.kz()[i] * k0d);
    return X;
}

// S-matrix between gap-medium ports: [b1; b2] = [[S11, S12], [S21, S22]] [a1; a2], port 1
// above (a1 down-going in, b1 up-going out), port 2 below (a2 up-going in, b2 down-going out).
struct SMatrix {
    Mat S11, S12, S21, S22;
    static SMatrix identity(int n) { return {Mat(n, n), Mat::identity(n), Mat::identity(n), Mat(n, n)}; }
};

// The fictitious gap medium: lossless, eps = 1 + max kt^2, so kz >= 1 for every order.
std::unique_ptr<LayerModes> gap_medium(const Harmonics& h) {
    double kt2 = 0.0;
    for (int i = 0; i < h.size(); ++i) kt2 = std::max(kt2, h.kx[i] * h.kx[i] + h.ky[i] * h.ky[i]);
    return uniform_modes(h, cplx(1.0 + kt2, 0.0));
}

// One layer between gaps ([Rumpf 2011, Eqs. 60-69] in our sign convention): with
// A = W^-1 W0 + V^-1 V0, B = W^-1 W0 - V^-1 V0 (W0 = I) and D = A - X B A^-1 X B,
// S11 = S22 = D^-1 (X B A^-1 X A - B),  S12 = S21 = D^-1 X (A - B A^-1 B).
SMatrix layer_smatrix(const LayerModes& m, double k0d, const LayerModes& gap) {
    const int n2 = static_cast<int>(m.kz().size());
    const Mat G = m.apply_W_inverse(Mat::identity(n2));
    const Mat H = m.apply_V_inverse(gap.apply_V(Mat::identity(n2)));
    Mat A(n2, n2), B(n2, n2);
    for (std::size_t q = 0; q < A.data.size(); ++q) {
        A.data[q] = G.data[q] + H.data[q];
        B.data[q] = G.data[q] - H.data[q];
    }
    const CVec X = propagation(m, k0d);
    auto scale_rows = [&](Mat M) {
        for (int j = 0; j < n2; ++j)
            for (int i = 0; i < n2; ++i) M(i, j) *= X[i];
        return M;
    };
    const Mat XB = scale_rows(B);
    const LU luA(A);
    Mat D = A;
    gemm(XB, luA.solve(XB), D, -1.0, 1.0);
    const LU luD(std::move(D));
    Mat num11 = B;
    gemm(XB, luA.solve(scale_rows(A)), num11, 1.0, -1.0);
    Mat num12 = A;
    gemm(B, luA.solve(B), num12, -1.0, 1.0);
    SMatrix s;
    s.S11 = luD.solve(num11);
    s.S12 = luD.solve(scale_rows(std::move(num12)));
    s.S21 = s.S12;
    s.S22 = s.S11;
    return s;
}

// Redheffer star product: a above b.
SMatrix star(const SMatrix& a, const SMatrix& b) {
    const int n2 = a.S11.rows;
    Mat I_BA = Mat::identity(n2);
    gemm(b.S11, a.S22, I_BA, -1.0, 1.0);  // I - B11 A22
    Mat I_AB = Mat::identity(n2);
    gemm(a.S22, b.S11, I_AB, -1.0, 1.0);  // I - A22 B11
    const LU lu1(std::move(I_BA)), lu2(std::move(I_AB));
    SMatrix s;
    s.S11 = a.S11;
    gemm(a.S12, lu1.solve(matmul(b.S11, a.S21)), s.S11, 1.0, 1.0);
    s.S12 = matmul(a.S12, lu1.solve(b.S12));
    s.S21 = matmul(b.S21, lu2.solve(a.S21));
    s.S22 = b.S22;
    gemm(b.S21, lu2.solve(matmul(a.S22, b.S12)), s.S22, 1.0, 1.0);
    return s;
}

}  // namespace

Mat project_out(const Basis& basis, const CVec& kz, cplx eps, double direction, const Mat& F, const Mat& G) {
    const int n = static_cast<int>(kz.size());
    const int cols = F.cols > 0 ? F.cols : G.cols;
    CVec kz_eps(static_cast<std::size_t>(n));  // direction kz / eps per order, out of the O(N^2) loop
    for (int i = 0; i < n; ++i) kz_eps[i] = direction * kz[i] / eps;
    Mat P(2 * n, cols);
    for (int j = 0; j < cols; ++j) {
        for (int i = 0; i < n; ++i) {
            cplx Es = 0.0, Ep = 0.0, hs = 0.0, hp = 0.0;
            if (F.cols > 0) {
                Es = basis.sx[i] * F(i, j) + basis.sy[i] * F(n + i, j);
                Ep = basis.px[i] * F(i, j) + basis.py[i] * F(n + i, j);
            }
            if (G.cols > 0) {
                hs = basis.sx[i] * G(i, j) + basis.sy[i] * G(n + i, j);
                hp = basis.px[i] * G(i, j) + basis.py[i] * G(n + i, j);
            }
            P(i, j) = kz[i] * Es + direction * hp;
            P(n + i, j) = Ep - kz_eps[i] * hs;
        }
    }
    return P;
}

Mat project_up(const StackProblem& pr, const Basis& basis, const CVec& kz, const Mat& F, const Mat& G) {
    return project_out(basis, kz, pr.eps_superstrate, 1.0, F, G);
}

void incident_fields(const StackProblem& pr, const Basis& basis, const CVec& kz_superstrate, Mat& Finc, Mat& Ginc) {
    const int n = pr.harmonics.size(), n2 = 2 * n;
    const int i0 = pr.zero_order;
    const cplx eps1 = pr.eps_superstrate;
    const cplx kz0 = kz_superstrate[i0];
    Finc = Mat(n2, 2);
    Ginc = Mat(n2, 2);
    Finc(i0, 0) = basis.sx[i0];
    Finc(n + i0, 0) = basis.sy[i0];
    Ginc(i0, 0) = kz0 * basis.px[i0];
    Ginc(n + i0, 0) = kz0 * basis.py[i0];
    Finc(i0, 1) = -kz0 / eps1 * basis.px[i0];
    Finc(n + i0, 1) = -kz0 / eps1 * basis.py[i0];
    Ginc(i0, 1) = basis.sx[i0];
    Ginc(n + i0, 1) = basis.sy[i0];
}

void reflected_amplitudes(const Basis& basis, const Mat& psi, const Mat& phi, const Mat& Finc, const Mat& Ginc,
                          Mat& r) {
    const int n = psi.rows / 2;
    r = Mat(2 * n, psi.cols);
    for (int j = 0; j < psi.cols; ++j) {
        for (int i = 0; i < n; ++i) {
            r(i, j) = basis.sx[i] * (psi(i, j) - Finc(i, j)) + basis.sy[i] * (psi(n + i, j) - Finc(n + i, j));
            r(n + i, j) = basis.sx[i] * (phi(i, j) - Ginc(i, j)) + basis.sy[i] * (phi(n + i, j) - Ginc(n + i, j));
        }
    }
}

namespace {

// The top of the stack seen from the superstrate: any field there is [f; g] T for some
// T (2N), given as `projected` = project_up(f, g) and `fields`, which returns [f T, g T].
// Closes it with the superstrate (incident + outgoing waves) and returns T for unit s
// and p incidence (columns 0 and 1); fills out.r.
template <class Fields>
Mat close_top(const StackProblem& pr, const Basis& basis, Mat projected, const Fields& fields, StackSolution& out) {
    Mat Finc, Ginc;  // the incident waves (down-going in the superstrate), s in column 0 and p in column 1
    incident_fields(pr, basis, out.kz_superstrate, Finc, Ginc);
    const LU top(std::move(projected));
    Mat T = top.solve(project_up(pr, basis, out.kz_superstrate, Finc, Ginc));
    const auto [psi, phi] = fields(T);
    reflected_amplitudes(basis, psi, phi, Finc, Ginc, out.r);
    return T;
}

Mat close_top(const StackProblem& pr, const Basis& basis, const Mat& f, const Mat& g, StackSolution& out) {
    return close_top(pr, basis, project_up(pr, basis, out.kz_superstrate, f, g),
                     [&](const Mat& T) { return std::make_pair(matmul(f, T), matmul(g, T)); }, out);
}

// D F for F whose nonzeros lie in the 2 x 2 blocks {i, N + i} x {i, N + i} of each order,
// as the half-spaces' outgoing columns do: O(N^2) instead of a product.
Mat times_order_blocks(const Mat& D, const Mat& F) {
    const int n = F.rows / 2;
    Mat out(D.rows, F.cols);
    for (int i = 0; i < n; ++i)
        for (int c : {i, n + i}) {
            const cplx a = F(i, c), b = F(n + i, c);
            for (int r = 0; r < D.rows; ++r) out(r, c) = D(r, i) * a + D(r, n + i) * b;
        }
    return out;
}

// Above the top layer the field is [W (I + R); V (R - I)] with R = X b a^-1 X. Its
// projection is assembled from project_up(W) and project_up(V), O(N^2) from a layer
// whose W and V are at hand, and one product with R.
Mat close_top_layer(const StackProblem& pr, const Basis& basis, const LayerModes& m, const Mat& R, StackSolution& out) {
    const Mat PW = project_up(pr, basis, out.kz_superstrate, m.W(), Mat());
    const Mat PV = project_up(pr, basis, out.kz_superstrate, Mat(), m.V());
    Mat projected(PW.rows, PW.cols), sum(PW.rows, PW.cols);
    for (std::size_t q = 0; q < PW.data.size(); ++q) {
        projected.data[q] = PW.data[q] - PV.data[q];
        sum.data[q] = PW.data[q] + PV.data[q];
    }
    gemm(sum, R, projected, 1.0, 1.0);
    auto fields = [&](const Mat& T) {
        const Mat RT = matmul(R, T);
        Mat plus = RT, minus = RT;
        for (std::size_t q = 0; q < RT.data.size(); ++q) {
            plus.data[q] += T.data[q];
            minus.data[q] -= T.data[q];
        }
        return std::make_pair(m.apply_W(plus), m.apply_V(minus));
    };
    return close_top(pr, basis, std::move(projected), fields, out);
}

void solve_etm(const StackProblem& pr, const Basis& basis, StackSolution& out) {
    Mat f, g;
    outgoing_columns(basis, out.kz_substrate, pr.eps_substrate, -1.0, f, g);
    if (pr.layers.empty()) {
        out.t = close_top(pr, basis, f, g, out);
        return;
    }
    const std::size_t bottom = pr.layers.size() - 1;
    auto inverses = [&](std::size_t k, const Mat& fk, const Mat& gk) {
        const LayerModes& m = *pr.layers[k];
        // The substrate's columns are sparse: times_order_blocks applies.
        if (k == bottom) return std::make_pair(times_order_blocks(m.W_inverse(), fk), times_order_blocks(m.V_inverse(), gk));
        return std::make_pair(m.apply_W_inverse(fk), m.apply_V_inverse(gk));
    };
    auto forward = [&](std::size_t k, const Mat& P, const Mat& M) {
        return std::make_pair(pr.layers[k]->apply_W(P), pr.layers[k]->apply_V(M));
    };
    auto kz = [&](std::size_t k) -> const CVec& { return pr.layers[k]->kz(); };
    EtmSweep sweep = etm_sweep(pr.layers.size(), pr.thickness, std::move(f), std::move(g), kz, inverses, forward);
    Mat T = close_top_layer(pr, basis, *pr.layers.front(), sweep.R, out);
    etm_walk_down(sweep.steps, T);
    out.t = std::move(T);
}

// One layer between the half-spaces, its boundary conditions at both interfaces solved at
// once, as for one grating layer in [Moharam 1995a, Sec. 2] (the
// tangential fields matched at z = 0 and z = d), here in the PQ form of
// modes.hpp with the half-spaces' rows of this file's header. With c_d the
// down-going mode amplitudes at the top of the layer and c_u the up-going ones at its
// bottom (so that only X = exp(i kz k0 d), |X| <= 1, appears), the field is
// [W (c_d + X c_u); V (X c_u - c_d)] at the top and [W (X c_d + c_u); V (c_u - X c_d)] at
// the bottom. The superstrate's rows (project_up, which annihilate its up-going waves) take
// the incident wave; the substrate's (project_out with direction -1, which annihilate its
// down-going, outgoing waves) give zero, since the field there is those waves alone:
//     [[L, R X], [R' X, L']] [c_d; c_u] = [project_up(inc); 0],
// L = project_up(W, -V), R = project_up(W, V), L' = project_out(-1)(W, V), R' = its (W, -V):
// one 4N x 4N LU factorization. It replaces the ETM step's explicit W^-1 and V^-1 (an LU
// factorization and inversion each) and its two 2N x 2N products and two factorizations
// (a lamellar layer then needs no inverse blocks either: LamellarParts::inverses).
// Where the substrate is the superstrate's medium (a free-standing layer: L' = L, R' = R),
// the stack is symmetric under z -> d - z, and the even and odd combinations e = c_d + c_u,
// o = c_d - c_u decouple: (L + R X) e = (L - R X) o = project_up(inc), two 2N x 2N LU
// factorizations, a quarter of the 4N one's work. All blocks are assembled in one pass over
// W and V from the s and p components of each mode's fields (boundary_blocks). r is
// measured from the field at the top (reflected_amplitudes), t from the field at the
// bottom: the substrate's s wave has E = s-hat and its p wave h = s-hat, and each's other
// field is along p-hat, so t_s = s-hat . E and t_p = s-hat . h, exact also where kz = 0
// in the substrate.
// Per mode j and order i, with Es, Ep the s and p components of W's column, hs, hp those of
// V's, a = kz Es, e = kz / eps hs in a half-space: project_up(W, -+V) = [a -+ hp; Ep +- e]
// and project_out(-1)(W, +-V) = [a' -+ hp; Ep +- e'].
template <class Write>
void boundary_blocks(const Basis& basis, const Mat& W, const Mat& V, const CVec& kz1, cplx eps1, const CVec& kz2,
                     cplx eps2, const Write& write) {
    const int n = W.rows / 2;
    CVec e1(static_cast<std::size_t>(n)), e2(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
        e1[i] = kz1[i] / eps1;
        e2[i] = kz2[i] / eps2;
    }
    for (int j = 0; j < W.cols; ++j) {
        const cplx* w = &W(0, j);
        const cplx* v = &V(0, j);
        for (int i = 0; i < n; ++i) {
            const cplx Es = basis.sx[i] * w[i] + basis.sy[i] * w[n + i];
            const cplx Ep = basis.px[i] * w[i] + basis.py[i] * w[n + i];
            const cplx hs = basis.sx[i] * v[i] + basis.sy[i] * v[n + i];
            const cplx hp = basis.px[i] * v[i] + basis.py[i] * v[n + i];
            write(i, j, kz1[i] * Es, kz2[i] * Es, Ep, hp, e1[i] * hs, e2[i] * hs);
        }
    }
}

// The mode amplitudes [c_d; c_u] (4N x cols) for the superstrate's projected incident
// waves `top` (2N x cols), by the 4N x 4N system or, where eps_substrate ==
// eps_superstrate, its even and odd halves (solve_direct).
Mat direct_amplitudes(const StackProblem& pr, const Basis& basis, const Mat& W, const Mat& V, const CVec& X,
                      const StackSolution& out, const Mat& top) {
    const int n2 = W.rows, n = n2 / 2, cols = top.cols;
    Mat c(2 * n2, cols);
    if (pr.eps_substrate == pr.eps_superstrate) {
        Mat even(n2, n2), odd(n2, n2);
        boundary_blocks(basis, W, V, out.kz_superstrate, pr.eps_superstrate, out.kz_substrate, pr.eps_substrate,
                        [&](int i, int j, cplx a, cplx, cplx Ep, cplx hp, cplx e, cplx) {
                            const cplx x = X[j], p = 1.0 + x, m = 1.0 - x;
                            even(i, j) = a * p - hp * m;
                            even(n + i, j) = Ep * p + e * m;
                            odd(i, j) = a * m - hp * p;
                            odd(n + i, j) = Ep * m + e * p;
                        });
        const Mat ce = LU(std::move(even)).solve(top), co = LU(std::move(odd)).solve(top);
        for (int k = 0; k < cols; ++k)
            for (int i = 0; i < n2; ++i) {
                c(i, k) = 0.5 * (ce(i, k) + co(i, k));
                c(n2 + i, k) = 0.5 * (ce(i, k) - co(i, k));
            }
        return c;
    }
    Mat M(2 * n2, 2 * n2);
    boundary_blocks(basis, W, V, out.kz_superstrate, pr.eps_superstrate, out.kz_substrate, pr.eps_substrate,
                    [&](int i, int j, cplx a1, cplx a2, cplx Ep, cplx hp, cplx e1, cplx e2) {
                        const cplx x = X[j];
                        M(i, j) = a1 - hp;
                        M(n + i, j) = Ep + e1;
                        M(i, n2 + j) = (a1 + hp) * x;
                        M(n + i, n2 + j) = (Ep - e1) * x;
                        M(n2 + i, j) = (a2 + hp) * x;
                        M(n2 + n + i, j) = (Ep - e2) * x;
                        M(n2 + i, n2 + j) = a2 - hp;
                        M(n2 + n + i, n2 + j) = Ep + e2;
                    });
    for (int k = 0; k < cols; ++k)
        for (int i = 0; i < n2; ++i) c(i, k) = top(i, k);
    return LU(std::move(M)).solve(c);
}

void solve_direct(const StackProblem& pr, const Basis& basis, StackSolution& out) {
    const LayerModes& m = *pr.layers.front();
    const int n2 = 2 * pr.harmonics.size(), n = n2 / 2;
    const CVec X = propagation(m, pr.thickness.front());
    Mat Finc, Ginc;
    incident_fields(pr, basis, out.kz_superstrate, Finc, Ginc);
    const Mat top = project_up(pr, basis, out.kz_superstrate, Finc, Ginc);
    Mat c;
    {
        Mat W_copy, V_copy;  // only for layers that do not store W and V (LayerModes::stored_W)
        const Mat* W = m.stored_W();
        const Mat* V = m.stored_V();
        if (!W) W = &(W_copy = m.W());
        if (!V) V = &(V_copy = m.V());
        c = direct_amplitudes(pr, basis, *W, *V, X, out, top);
    }
    Mat top_plus(n2, 2), top_minus(n2, 2), bottom_plus(n2, 2), bottom_minus(n2, 2);
    for (int j = 0; j < 2; ++j)
        for (int i = 0; i < n2; ++i) {
            const cplx d = c(i, j), u = c(n2 + i, j);
            top_plus(i, j) = d + X[i] * u;
            top_minus(i, j) = X[i] * u - d;
            bottom_plus(i, j) = X[i] * d + u;
            bottom_minus(i, j) = u - X[i] * d;
        }
    reflected_amplitudes(basis, m.apply_W(top_plus), m.apply_V(top_minus), Finc, Ginc, out.r);
    const Mat psi = m.apply_W(bottom_plus), phi = m.apply_V(bottom_minus);
    out.t = Mat(n2, 2);
    for (int j = 0; j < 2; ++j)
        for (int i = 0; i < n; ++i) {
            out.t(i, j) = basis.sx[i] * psi(i, j) + basis.sy[i] * psi(n + i, j);
            out.t(n + i, j) = basis.sx[i] * phi(i, j) + basis.sy[i] * phi(n + i, j);
        }
    out.direct = true;
}

void solve_smatrix(const StackProblem& pr, const Basis& basis, StackSolution& out) {
    const int n2 = 2 * pr.harmonics.size();
    const auto gap = gap_medium(pr.harmonics);
    SMatrix total = SMatrix::identity(n2);
    for (std::size_t k = 0; k < pr.layers.size(); ++k) {
        SMatrix layer = layer_smatrix(*pr.layers[k], pr.thickness[k], *gap);
        total = k == 0 ? std::move(layer) : star(total, layer);
    }

    // Bottom: the gap fields equal the substrate's outgoing waves, [psi; phi] = [F; G] t.
    // Gap amplitudes there: a2 (up, into the stack) = (F + V0^-1 G) t / 2, b2 (down) =
    // (F - V0^-1 G) t / 2, and b2 = S21 a1 + S22 a2 gives S21 a1 = Mb t.
    Mat F, G;
    outgoing_columns(basis, out.kz_substrate, pr.eps_substrate, -1.0, F, G);
    const Mat V0G = gap->apply_V_inverse(G);
    Mat up(n2, n2), down(n2, n2);
    for (std::size_t q = 0; q < up.data.size(); ++q) {
        up.data[q] = 0.5 * (F.data[q] + V0G.data[q]);
        down.data[q] = 0.5 * (F.data[q] - V0G.data[q]);
    }
    Mat Mb = down;
    gemm(total.S22, up, Mb, -1.0, 1.0);
    const LU luMb(std::move(Mb));
    // Top: b1 = R_eff a1, R_eff = S11 + S12 up Mb^-1 S21; field [a1 + b1; V0 (b1 - a1)].
    const Mat transfer = luMb.solve(total.S21);  // t = transfer a1
    Mat Reff = total.S11;
    gemm(total.S12, matmul(up, transfer), Reff, 1.0, 1.0);
    Mat plus = Reff, minus = Reff;
    for (int i = 0; i < n2; ++i) {
        plus(i, i) += 1.0;
        minus(i, i) -= 1.0;
    }
    const Mat a1 = close_top(pr, basis, plus, gap->apply_V(minus), out);
    out.t = matmul(transfer, a1);
}

}  // namespace

void etm_walk_down(const std::vector<EtmStep>& steps, Mat& T) {
    for (std::size_t k = steps.size(); k-- > 0;) {
        for (int j = 0; j < T.cols; ++j)
            for (int i = 0; i < T.rows; ++i) T(i, j) *= steps[k].X[i];
        T = steps[k].a.solve(T);
    }
}

CVec half_space_kz(const Harmonics& h, cplx eps) {
    CVec kz(h.size());
    for (int i = 0; i < h.size(); ++i) kz[i] = outgoing_sqrt(eps - h.kx[i] * h.kx[i] - h.ky[i] * h.ky[i]);
    return kz;
}

StackSolution solve_stack(const StackProblem& pr, StackMethod method) {
    if (pr.thickness.size() != pr.layers.size()) throw std::invalid_argument("solve_stack: one thickness per layer");
    const Basis basis = polarization_basis(pr);
    StackSolution out;
    out.kz_superstrate = half_space_kz(pr.harmonics, pr.eps_superstrate);
    out.kz_substrate = half_space_kz(pr.harmonics, pr.eps_substrate);
    if (method == StackMethod::EnhancedTransmittance && pr.direct_single_layer && pr.layers.size() == 1 &&
        pr.layers.front()->dense())
        solve_direct(pr, basis, out);
    else if (method == StackMethod::EnhancedTransmittance)
        solve_etm(pr, basis, out);
    else
        solve_smatrix(pr, basis, out);
    return out;
}

}  // namespace rcwa
