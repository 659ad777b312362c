// Enhanced transmittance matrix approach (Moharam, Pommet, Grann & Gaylord 1995, JOSA A 12,
// 1077, Eqs. 10-15), generalized to the PQ modes of modes.hpp. The stack is walked from
// the substrate up; each layer's growing exponential is never formed (only X = e^{i kz d},
// |X| <= 1, appears), so thick and lossy layers stay stable.
//
// The half-spaces enter only through their outgoing waves, as tall 4N x 2N matrices whose
// columns stay independent at kz = 0 (s waves normalized by E, p waves by h): an order
// grazing the superstrate or substrate (a Rayleigh anomaly) is solved exactly, without
// dividing by kz. At the top, a 2N x 4N projection that annihilates the reflected waves
// (rows kz E_s + h_p and E_p - kz/eps h_s per order) gives a 2N x 2N system.
#include "stack.hpp"

#include <cmath>

namespace rcwa {

namespace {

struct Basis {
    std::vector<double> sx, sy, px, py;  // s-hat and p-hat (tangential) per harmonic
};

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

CVec half_space_kz(const Harmonics& h, cplx eps) {
    CVec kz(h.size());
    for (int i = 0; i < h.size(); ++i) kz[i] = outgoing_sqrt(eps - h.kx[i] * h.kx[i] - h.ky[i] * h.ky[i]);
    return kz;
}

// Columns: s wave of harmonic i at i, p wave at N + i. direction = +1 up-going, -1 down-going.
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

struct LayerStep {
    LU a;
    CVec X;
};

}  // namespace

StackSolution solve_stack(const StackProblem& pr) {
    const int n = pr.harmonics.size();
    const int n2 = 2 * n;
    const std::size_t nl = pr.layers.size();
    if (pr.thickness.size() != nl) throw std::invalid_argument("solve_stack: one thickness per layer");
    const Basis basis = polarization_basis(pr);

    StackSolution out;
    out.kz_superstrate = half_space_kz(pr.harmonics, pr.eps_superstrate);
    out.kz_substrate = half_space_kz(pr.harmonics, pr.eps_substrate);

    Mat f, g;
    outgoing_columns(basis, out.kz_substrate, pr.eps_substrate, -1.0, f, g);

    std::vector<LayerStep> steps;
    steps.reserve(nl);
    for (std::size_t k = nl; k-- > 0;) {
        const LayerModes& m = *pr.layers[k];
        const Mat Wf = m.apply_W_inverse(f);
        const Mat Vg = m.apply_V_inverse(g);
        Mat a(n2, n2), b(n2, n2);
        for (std::size_t q = 0; q < a.data.size(); ++q) {
            a.data[q] = 0.5 * (Wf.data[q] - Vg.data[q]);
            b.data[q] = 0.5 * (Wf.data[q] + Vg.data[q]);
        }
        CVec X(n2);
        for (int i = 0; i < n2; ++i) X[i] = std::exp(cplx(0.0, 1.0) * m.kz()[i] * pr.thickness[k]);
        LU lu(std::move(a));
        Mat XMX = lu.solve_right(b);  // b a^{-1}
        for (int j = 0; j < n2; ++j)
            for (int i = 0; i < n2; ++i) XMX(i, j) *= X[i] * X[j];
        Mat plus = XMX, minus = XMX;
        for (int i = 0; i < n2; ++i) {
            plus(i, i) += 1.0;
            minus(i, i) -= 1.0;
        }
        f = m.apply_W(plus);
        g = m.apply_V(minus);
        steps.push_back(LayerStep{std::move(lu), std::move(X)});
    }

    // Incident waves (down-going in the superstrate), s in column 0 and p in column 1.
    const int i0 = pr.zero_order;
    const cplx eps1 = pr.eps_superstrate;
    const cplx kz0 = out.kz_superstrate[i0];
    Mat Finc(n2, 2), Ginc(n2, 2);
    Finc(i0, 0) = basis.sx[i0];
    Finc(n + i0, 0) = basis.sy[i0];
    Ginc(i0, 0) = kz0 * basis.px[i0];
    Ginc(n + i0, 0) = kz0 * basis.py[i0];
    Finc(i0, 1) = -kz0 / eps1 * basis.px[i0];
    Finc(n + i0, 1) = -kz0 / eps1 * basis.py[i0];
    Ginc(i0, 1) = basis.sx[i0];
    Ginc(n + i0, 1) = basis.sy[i0];

    // Projection that annihilates the up-going superstrate waves.
    auto project = [&](const Mat& F, const Mat& G) {
        Mat P(n2, F.cols);
        for (int j = 0; j < F.cols; ++j) {
            for (int i = 0; i < n; ++i) {
                const cplx Es = basis.sx[i] * F(i, j) + basis.sy[i] * F(n + i, j);
                const cplx Ep = basis.px[i] * F(i, j) + basis.py[i] * F(n + i, j);
                const cplx hs = basis.sx[i] * G(i, j) + basis.sy[i] * G(n + i, j);
                const cplx hp = basis.px[i] * G(i, j) + basis.py[i] * G(n + i, j);
                const cplx kz = out.kz_superstrate[i];
                P(i, j) = kz * Es + hp;
                P(n + i, j) = Ep - kz / eps1 * hs;
            }
        }
        return P;
    };
    const LU top(project(f, g));
    Mat T = top.solve(project(Finc, Ginc));

    const Mat psi = matmul(f, T), phi = matmul(g, T);
    out.r = Mat(n2, 2);
    for (int j = 0; j < 2; ++j) {
        for (int i = 0; i < n; ++i) {
            out.r(i, j) = basis.sx[i] * (psi(i, j) - Finc(i, j)) + basis.sy[i] * (psi(n + i, j) - Finc(n + i, j));
            out.r(n + i, j) = basis.sx[i] * (phi(i, j) - Ginc(i, j)) + basis.sy[i] * (phi(n + i, j) - Ginc(n + i, j));
        }
    }
    // Walk down: T_below = a^{-1} X T_above (steps were stored bottom layer first).
    for (std::size_t k = steps.size(); k-- > 0;) {
        for (int j = 0; j < T.cols; ++j)
            for (int i = 0; i < n2; ++i) T(i, j) *= steps[k].X[i];
        T = steps[k].a.solve(T);
    }
    out.t = std::move(T);
    return out;
}

}  // namespace rcwa
