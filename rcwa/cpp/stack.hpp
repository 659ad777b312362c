// Reflection and transmission of a layer stack between two half-spaces.
#pragma once

#include <tuple>
#include <utility>

#include "modes.hpp"

namespace rcwa {

struct StackProblem {
    Harmonics harmonics;
    int zero_order = 0;        // index of the specular harmonic (the incident wave's)
    cplx eps_superstrate;      // must be real and positive (lossless incidence medium)
    cplx eps_substrate;
    double s_x = 0.0, s_y = 1.0;  // s direction used where kx = ky = 0 (from the plane of incidence)
    std::vector<const LayerModes*> layers;  // from the superstrate down
    std::vector<double> thickness;          // k0 * d of each layer
    // One dense layer (LayerModes::dense) with the ETM: solve its 4N x 4N boundary system
    // directly instead, or its even and odd 2N x 2N halves where the substrate is the
    // superstrate's medium (stack.cpp, solve_direct; `direct` in the solution).
    bool direct_single_layer = false;
};

// Outgoing amplitudes for unit s and unit p incidence (columns 0 and 1). Row i is the s
// amplitude of harmonic i (E along s-hat), row N + i the p amplitude (h along s-hat).
// The incident s wave has E = s-hat, the incident p wave h = s-hat (h = Z0 H).
struct StackSolution {
    Mat r;         // 2N x 2
    Mat t;         // 2N x 2
    CVec kz_superstrate;  // N, outgoing branch
    CVec kz_substrate;    // N
    bool decoupled = false;  // solved per polarization on N x N blocks (polarized.hpp)
    bool direct = false;     // one dense layer's boundary system solved at once (solve_stack)
    int sectors_solved = 0;  // mirror-symmetry sectors solved, of sectors_total (sectors.hpp); 0 of 0: not used
    int sectors_total = 0;
    int hermitian_solves = 0;  // eigen-solves done by Hermitian solvers (lossless layers: LamellarParts)
    int real_solves = 0;       // of those, done in real arithmetic (dsyevd / dsygvd: real_by_phase)
    int inverse_iteration_solves = 0;  // general 1D eigen-solves done by eig_small (linalg.hpp)
    int complex_symmetric_solves = 0;  // general 1D eigen-solves done as complex symmetric (complex_symmetric.hpp)
};

// kz of every harmonic in a half-space of permittivity eps, outgoing branch (outgoing_sqrt).
CVec half_space_kz(const Harmonics& h, cplx eps);

enum class StackMethod {
    // Redheffer star product of layer scattering matrices ([Redheffer 1961]; [Rumpf 2011,
    // Eqs. 60-73]; as in S4, [Liu 2012]). Gives both sides of the stack.
    ScatteringMatrix,
    // Enhanced transmittance matrix [Moharam 1995b]: one bottom-up sweep, about half the
    // work for a one-sided solve.
    EnhancedTransmittance,
};

StackSolution solve_stack(const StackProblem& problem, StackMethod method = StackMethod::EnhancedTransmittance);

// The half-spaces' parts of the stack, shared with the mirror-sector solve (sectors.hpp).
struct Basis {
    std::vector<double> sx, sy, px, py;  // s-hat and p-hat (tangential) per harmonic
};
Basis polarization_basis(const StackProblem& problem);
// The outgoing waves of a half-space, 2N x 2N for psi (F) and phi (G): the s wave of
// harmonic i in column i, the p wave in column N + i. direction = +1 up-going, -1 down-going.
void outgoing_columns(const Basis& basis, const CVec& kz, cplx eps, double direction, Mat& F, Mat& G);
// The rows that annihilate the superstrate's up-going waves (kz E_s + h_p and
// E_p - kz/eps h_s per order), applied to a field [F; G] at the top of the stack; an
// empty F or G counts as zero.
Mat project_up(const StackProblem& problem, const Basis& basis, const CVec& kz, const Mat& F, const Mat& G);
// The same for a half-space of permittivity eps whose waves going in `direction` (+1 up,
// -1 down) are annihilated: rows kz E_s + direction h_p and E_p - direction kz/eps h_s.
Mat project_out(const Basis& basis, const CVec& kz, cplx eps, double direction, const Mat& F, const Mat& G);
// The incident waves' psi and phi (2N x 2): unit s in column 0, unit p in column 1.
void incident_fields(const StackProblem& problem, const Basis& basis, const CVec& kz_superstrate, Mat& Finc, Mat& Ginc);
// r (2N x cols) from the total field [psi; phi] at the top of the stack: the s
// amplitudes of psi - Finc (E along s-hat) and of phi - Ginc (h along s-hat).
void reflected_amplitudes(const Basis& basis, const Mat& psi, const Mat& phi, const Mat& Finc, const Mat& Ginc, Mat& r);


// The enhanced transmittance sweep ([Moharam 1995b, Eqs. 10-15]), shared by the full stack
// (stack.cpp), one polarization on N x N blocks (polarized.cpp) and one mirror-symmetry sector (sectors.cpp), which differ only
// in how a layer's W, V and their inverses are applied. From the substrate up, layer k
// (with f, g the field entering it from below) gets a = (W^-1 f - V^-1 g) / 2,
// b = (W^-1 f + V^-1 g) / 2, X = exp(i kz k0 d) and X b a^-1 X, and passes up
// f = W (I + X b a^-1 X), g = V (X b a^-1 X - I).
struct EtmStep {
    LU a;
    CVec X;
};
struct EtmSweep {
    std::vector<EtmStep> steps;  // bottom layer first
    Mat R;                       // X b a^-1 X of the top layer
};
// `layers` layers, from the top (0) down; kz(k): layer k's kz; inverses(k, f, g): the pair
// (W_k^-1 f, V_k^-1 g), where the bottom layer's f, g are whatever the caller's substrate
// form is (`f`, `g` as given); forward(k, P, M): the pair (W_k P, V_k M).
template <class Kz, class Inverses, class Forward>
EtmSweep etm_sweep(std::size_t layers, const std::vector<double>& k0d, Mat f, Mat g, const Kz& kz,
                   const Inverses& inverses, const Forward& forward) {
    EtmSweep out;
    out.steps.reserve(layers);
    for (std::size_t k = layers; k-- > 0;) {
        const auto [Wf, Vg] = inverses(k, f, g);
        const int n = Wf.rows;
        Mat a(n, n), b(n, n);
        for (std::size_t q = 0; q < a.data.size(); ++q) {
            a.data[q] = 0.5 * (Wf.data[q] - Vg.data[q]);
            b.data[q] = 0.5 * (Wf.data[q] + Vg.data[q]);
        }
        const CVec& kzk = kz(k);
        CVec X(kzk.size());
        for (std::size_t i = 0; i < X.size(); ++i) X[i] = std::exp(cplx(0.0, 1.0) * kzk[i] * k0d[k]);
        LU lu(std::move(a));
        Mat XMX = lu.solve_right(b);  // b a^-1
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) XMX(i, j) *= X[i] * X[j];
        out.steps.push_back(EtmStep{std::move(lu), std::move(X)});
        if (k == 0) {
            out.R = std::move(XMX);
            break;
        }
        Mat plus = XMX, minus = XMX;
        for (int i = 0; i < n; ++i) {
            plus(i, i) += 1.0;
            minus(i, i) -= 1.0;
        }
        std::tie(f, g) = forward(k, plus, minus);
    }
    return out;
}
// The amplitudes below each layer from those above the top one: T_below = a^-1 X T_above.
void etm_walk_down(const std::vector<EtmStep>& steps, Mat& T);

}  // namespace rcwa
