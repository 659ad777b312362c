// Mirror-symmetry sectors (sectors.hpp): the sector bases, the layers' modes in them, and
// the enhanced transmittance stack of stack.cpp ([Moharam 1995b, Eqs. 10-15]) written for
// dense sector-sized operators. Every formula is
// the 2N x 2N one of stack.cpp sandwiched between the sector bases, so the two agree to
// round-off (tests/rcwa/test_sectors.py).
#include "sectors.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <utility>

namespace rcwa {

namespace {

// A phased permutation of a vector space: (S v)[perm[i]] = coef[i] v[i].
struct Action {
    std::vector<int> perm;
    CVec coef;
};

Action identity_action(int n) {
    Action a{std::vector<int>(n), CVec(n, 1.0)};
    for (int i = 0; i < n; ++i) a.perm[i] = i;
    return a;
}

Action compose(const Action& a, const Action& b) {  // a after b
    const std::size_t n = b.perm.size();
    Action c{std::vector<int>(n), CVec(n)};
    for (std::size_t i = 0; i < n; ++i) {
        c.perm[i] = a.perm[b.perm[i]];
        c.coef[i] = a.coef[b.perm[i]] * b.coef[i];
    }
    return c;
}

// One mirror's action on the three 2N spaces: psi = [Ex; Ey], phi = [hx; hy], and the
// plane waves' amplitudes [s; p].
struct Actions {
    Action E, H, A;
};

// The harmonics must map onto their images to round-off (phi = 90 deg gives kx0 = 6e-17
// sin theta, not 0); a point nearer the mirror plane than that is solved as on it, which
// changes its answer by about as much.
constexpr double kHarmonicTolerance = 1e-14;
constexpr double kNegligible = 1e-14;
bool close(double a, double b) { return std::abs(a - b) <= kHarmonicTolerance * std::max(1.0, std::abs(b)); }

// Nothing where the point's harmonics or s-hat do not respect the mirror (sectors.hpp).
std::optional<Actions> mirror_actions(const Mirror& m, const StackProblem& sp, const Basis& b) {
    const Harmonics& h = sp.harmonics;
    const int n = h.size();
    if (static_cast<int>(m.partner.size()) != n || static_cast<int>(m.phase.size()) != n) return std::nullopt;
    const double mx = m.axis == 0 ? -1.0 : 1.0, my = -mx;  // M = diag(mx, my) on tangential vectors
    Actions out;
    for (Action* a : {&out.E, &out.H, &out.A}) *a = Action{std::vector<int>(2 * n), CVec(2 * n)};
    for (int i = 0; i < n; ++i) {
        const int j = m.partner[i];
        if (j < 0 || j >= n || m.partner[j] != i) return std::nullopt;
        if (!close(h.kx[j], mx * h.kx[i]) || !close(h.ky[j], my * h.ky[i])) return std::nullopt;
        const cplx p = m.phase[i];
        // E polar: (Ex, Ey) -> M (Ex, Ey); h axial: -M.
        out.E.perm[i] = j, out.E.coef[i] = mx * p;
        out.E.perm[n + i] = n + j, out.E.coef[n + i] = my * p;
        out.H.perm[i] = j, out.H.coef[i] = -mx * p;
        out.H.perm[n + i] = n + j, out.H.coef[n + i] = -my * p;
        // An s wave (E = s-hat_i) maps to E = M s-hat_i = sigma s-hat_{i'}; a p wave (h = s-hat_i)
        // to h = -M s-hat_i = -sigma s-hat_{i'}.
        const double sigma = b.sx[j] * mx * b.sx[i] + b.sy[j] * my * b.sy[i];
        if (std::abs(std::abs(sigma) - 1.0) > kSymmetryTolerance) return std::nullopt;
        const double sign = sigma > 0 ? 1.0 : -1.0;
        out.A.perm[i] = j, out.A.coef[i] = sign * p;
        out.A.perm[n + i] = n + j, out.A.coef[n + i] = -sign * p;
    }
    return out;
}

// Whether S M S^-1 = parity M for the scalar action S of the mirror (squared magnitudes:
// no hypot in an O(N^2) loop).
bool commutes(const Mat& M, const Mirror& m, double parity) {
    double largest = 0.0, worst = 0.0;
    for (int j = 0; j < M.cols; ++j)
        for (int i = 0; i < M.rows; ++i) {
            largest = std::max(largest, std::norm(M(i, j)));
            const cplx image = parity * m.phase[i] * std::conj(m.phase[j]) * M(i, j);
            worst = std::max(worst, std::norm(M(m.partner[i], m.partner[j]) - image));
        }
    return worst <= kSymmetryTolerance * kSymmetryTolerance * largest;
}

// Every layer respects the mirror: uniform, or general with [[eps]], Exx, Eyy even and
// Exy, Eyx odd (sectors.hpp).
bool layers_respect(const SweepProblem& pr, const Mirror& m) {
    const std::size_t n = pr.dkx.size();
    if (m.partner.size() != n || m.phase.size() != n) return false;
    for (const LayerInput& in : pr.layers) {
        if (in.kind == LayerKind::Uniform) continue;
        if (in.kind != LayerKind::General) return false;
        const auto& M = in.matrices;
        if (!commutes(M[0], m, 1.0) || !commutes(M[1], m, 1.0) || !commutes(M[2], m, -1.0) ||
            !commutes(M[3], m, -1.0) || !commutes(M[4], m, 1.0))
            return false;
    }
    return true;
}

// Sparse orthonormal columns: column a is sum over its entries of coef e_row.
struct Entry {
    int row;
    cplx coef;
};
using Columns = std::vector<std::vector<Entry>>;

// The group: every product of the mirrors, with which mirrors it contains.
struct Element {
    Action action;
    std::vector<int> mirrors;
};

// The basis of the sector with characters chi (one +-1 per mirror): P_chi e_j, normalized,
// for the first j of each orbit.
Columns sector_columns(const std::vector<Element>& group, const std::vector<double>& chi, int dim) {
    Columns cols;
    std::vector<bool> seen(dim, false);
    const double weight = 1.0 / static_cast<double>(group.size());
    for (int j = 0; j < dim; ++j) {
        if (seen[j]) continue;
        std::vector<Entry> v;
        for (const Element& g : group) {
            double character = 1.0;
            for (int k : g.mirrors) character *= chi[k];
            const int row = g.action.perm[j];
            seen[row] = true;
            const cplx c = weight * character * g.action.coef[j];
            auto it = std::find_if(v.begin(), v.end(), [&](const Entry& e) { return e.row == row; });
            if (it == v.end())
                v.push_back({row, c});
            else
                it->coef += c;
        }
        double norm2 = 0.0;
        for (const Entry& e : v) norm2 += std::norm(e.coef);
        if (norm2 < 1e-12) continue;  // this orbit has no vector in the sector
        std::vector<Entry> column;
        for (const Entry& e : v)
            if (std::abs(e.coef) > 1e-14) column.push_back({e.row, e.coef / std::sqrt(norm2)});
        cols.push_back(std::move(column));
    }
    return cols;
}

// L^H A R.
Mat reduce(const Mat& A, const Columns& L, const Columns& R) {
    Mat out(static_cast<int>(L.size()), static_cast<int>(R.size()));
    for (int b = 0; b < out.cols; ++b)
        for (int a = 0; a < out.rows; ++a) {
            cplx sum = 0.0;
            for (const Entry& l : L[a])
                for (const Entry& r : R[b]) sum += std::conj(l.coef) * A(l.row, r.row) * r.coef;
            out(a, b) = sum;
        }
    return out;
}

// U X, with `rows` rows.
Mat expand(const Columns& U, const Mat& X, int rows) {
    Mat out(rows, X.cols);
    for (int c = 0; c < X.cols; ++c)
        for (int a = 0; a < X.rows; ++a)
            for (const Entry& e : U[a]) out(e.row, c) += e.coef * X(a, c);
    return out;
}

// U^H Y.
Mat gather(const Columns& U, const Mat& Y) {
    Mat out(static_cast<int>(U.size()), Y.cols);
    for (int c = 0; c < Y.cols; ++c)
        for (int a = 0; a < out.rows; ++a) {
            cplx sum = 0.0;
            for (const Entry& e : U[a]) sum += std::conj(e.coef) * Y(e.row, c);
            out(a, c) = sum;
        }
    return out;
}

// A uniform layer in a sector: W = I (each basis vector of psi is a mode: its orders share
// kz), V and V^-1 the full ones (modes.cpp, UniformModes) reduced.
class ReducedUniform : public LayerModes {
  public:
    ReducedUniform(const LayerModes& full, const Columns& UE, const Columns& UH) {
        const int n2 = static_cast<int>(full.kz().size());
        V_ = reduce(full.apply_V(Mat::identity(n2)), UH, UE);
        V_inv_ = reduce(full.apply_V_inverse(Mat::identity(n2)), UE, UH);
        for (const auto& column : UE) kz_.push_back(full.kz()[column.front().row]);
    }
    Mat apply_W(const Mat& B) const override { return B; }
    Mat apply_W_inverse(const Mat& B) const override { return B; }
    Mat apply_V(const Mat& B) const override { return matmul(V_, B); }
    Mat apply_V_inverse(const Mat& B) const override { return matmul(V_inv_, B); }
    Mat V() const override { return V_; }

  private:
    Mat V_, V_inv_;
};

// A general layer in a sector: the eigen-solve of P_s Q_s (modes.cpp, general_modes).
std::unique_ptr<LayerModes> reduced_general(const Mat& P, const Mat& Q, const Columns& UE, const Columns& UH) {
    const Mat Ps = reduce(P, UE, UH), Qs = reduce(Q, UH, UE);
    Eigen e = eig(matmul(Ps, Qs));
    const int n = Ps.rows;
    CVec kz(n);
    for (int i = 0; i < n; ++i) kz[i] = layer_kz(e.values[i]);
    Mat V = matmul(Qs, e.vectors);
    for (int j = 0; j < n; ++j) {
        const cplx inv_kz = 1.0 / kz[j];
        for (int i = 0; i < n; ++i) V(i, j) *= inv_kz;
    }
    return std::make_unique<DenseModes>(std::move(e.vectors), std::move(V), std::move(kz));
}

// What every sector shares: the full problem's half-space waves and layer operators.
struct Shared {
    Basis basis;
    Mat F, G;        // substrate's outgoing (down-going) waves
    Mat Finc, Ginc;  // incident waves
    std::vector<Mat> P, Q;                               // general layers
    std::vector<std::unique_ptr<LayerModes>> uniform;    // uniform layers (full size)
};

struct SectorSolution {
    Mat psi, phi;  // total field at the top, sector coefficients (n x 2)
    Mat t;         // substrate amplitudes, sector coefficients (n x 2)
};

// The enhanced transmittance stack of stack.cpp (solve_etm, close_top_layer) in one sector.
SectorSolution sector_etm(const StackProblem& sp, const Shared& sh, const std::vector<const LayerModes*>& layers,
                          const Columns& UE, const Columns& UH, const Columns& D, const CVec& kz1) {
    const int n = static_cast<int>(D.size()), n2_full = 2 * sp.harmonics.size();
    auto inverses = [&](std::size_t k, const Mat& f, const Mat& g) {
        return std::make_pair(layers[k]->apply_W_inverse(f), layers[k]->apply_V_inverse(g));
    };
    auto forward = [&](std::size_t k, const Mat& P, const Mat& M) {
        return std::make_pair(layers[k]->apply_W(P), layers[k]->apply_V(M));
    };
    auto kz = [&](std::size_t k) -> const CVec& { return layers[k]->kz(); };
    EtmSweep sweep = etm_sweep(layers.size(), sp.thickness, reduce(sh.F, UE, D), reduce(sh.G, UH, D), kz, inverses, forward);
    const Mat& R = sweep.R;
    // Close with the superstrate: above the top layer the field is [W (I + R); V (R - I)] T.
    const LayerModes& top = *layers.front();
    const Mat PW = gather(D, project_up(sp, sh.basis, kz1, expand(UE, top.W(), n2_full), Mat()));
    const Mat PV = gather(D, project_up(sp, sh.basis, kz1, Mat(), expand(UH, top.V(), n2_full)));
    Mat projected(n, n), sum(n, n);
    for (std::size_t q = 0; q < PW.data.size(); ++q) {
        projected.data[q] = PW.data[q] - PV.data[q];
        sum.data[q] = PW.data[q] + PV.data[q];
    }
    gemm(sum, R, projected, 1.0, 1.0);
    Mat T = LU(std::move(projected)).solve(gather(D, project_up(sp, sh.basis, kz1, sh.Finc, sh.Ginc)));
    const Mat RT = matmul(R, T);
    Mat plus = RT, minus = RT;
    for (std::size_t q = 0; q < RT.data.size(); ++q) {
        plus.data[q] += T.data[q];
        minus.data[q] -= T.data[q];
    }
    SectorSolution out{top.apply_W(plus), top.apply_V(minus), Mat()};
    etm_walk_down(sweep.steps, T);
    out.t = std::move(T);
    return out;
}

// t of the harmonics where the sectors' s-hat differs from the caller's (kt = 0): the
// substrate wave's fields F t, G t there measured along the caller's s-hat.
void to_user_basis(const Shared& sh, const Basis& user, Mat& t) {
    const int n = t.rows / 2;
    for (int i = 0; i < n; ++i) {
        if (user.sx[i] == sh.basis.sx[i] && user.sy[i] == sh.basis.sy[i]) continue;
        for (int c = 0; c < t.cols; ++c) {
            const cplx ts = t(i, c), tp = t(n + i, c);
            const cplx Ex = sh.F(i, i) * ts + sh.F(i, n + i) * tp, Ey = sh.F(n + i, i) * ts + sh.F(n + i, n + i) * tp;
            const cplx hx = sh.G(i, i) * ts + sh.G(i, n + i) * tp, hy = sh.G(n + i, i) * ts + sh.G(n + i, n + i) * tp;
            t(i, c) = user.sx[i] * Ex + user.sy[i] * Ey;
            t(n + i, c) = user.sx[i] * hx + user.sy[i] * hy;
        }
    }
}

void add(Mat& total, const Mat& part) {
    for (std::size_t q = 0; q < total.data.size(); ++q) total.data[q] += part.data[q];
}

}  // namespace

std::vector<Mirror> respected_mirrors(const SweepProblem& pr) {
    std::vector<Mirror> out;
    for (const Mirror& m : pr.mirrors)
        if (layers_respect(pr, m)) out.push_back(m);
    return out;
}

std::vector<Mirror> respected_mirrors(const SweepProblem& pr, const StackProblem& sp) {
    StackProblem internal = sp;  // the sectors' basis (solve_sectors): s-hat = y where kt = 0
    internal.s_x = 0.0;
    internal.s_y = 1.0;
    const Basis basis = polarization_basis(internal);
    std::vector<Mirror> out;
    for (const Mirror& m : pr.mirrors)
        if (mirror_actions(m, sp, basis) && layers_respect(pr, m)) out.push_back(m);
    return out;
}

Mat laurent_inverse(const Mat& E, const std::vector<Mirror>& mirrors) {
    const int n = E.rows;
    if (mirrors.empty()) return LU(E).inverse();
    std::vector<Element> group;
    const int k = static_cast<int>(mirrors.size());
    for (int subset = 0; subset < (1 << k); ++subset) {
        Element g{identity_action(n), {}};
        for (int m = 0; m < k; ++m)
            if (subset & (1 << m)) {
                g.action = compose(Action{mirrors[m].partner, mirrors[m].phase}, g.action);
                g.mirrors.push_back(m);
            }
        group.push_back(std::move(g));
    }
    Mat Z(n, n);
    int total = 0;
    for (int s = 0; s < (1 << k); ++s) {
        std::vector<double> chi(k);
        for (int m = 0; m < k; ++m) chi[m] = (s & (1 << m)) ? -1.0 : 1.0;
        const Columns U = sector_columns(group, chi, n);
        if (U.empty()) continue;
        total += static_cast<int>(U.size());
        const Mat Zb = LU(reduce(E, U, U)).inverse();
        for (int b = 0; b < Zb.cols; ++b)
            for (int a = 0; a < Zb.rows; ++a)
                for (const Entry& ea : U[a])
                    for (const Entry& eb : U[b]) Z(ea.row, eb.row) += ea.coef * Zb(a, b) * std::conj(eb.coef);
    }
    if (total != n) return LU(E).inverse();
    return Z;
}

std::optional<StackSolution> solve_sectors(const SweepProblem& pr, const StackProblem& sp,
                                           const std::vector<Mirror>& mirrors, Incidence incidence,
                                           const std::vector<Mat>& Z) {
    if (pr.method != StackMethod::EnhancedTransmittance || pr.layers.empty()) return std::nullopt;
    const int n = sp.harmonics.size(), n2 = 2 * n;
    // The sectors' own s and p basis: where kt = 0 (normal incidence) s-hat = y, which every
    // mirror maps to +-itself, whatever the s-hat the caller chose there (`user`); r is
    // measured in the caller's (reflected_amplitudes, from the fields), t converted to it.
    StackProblem internal = sp;
    internal.s_x = 0.0;
    internal.s_y = 1.0;
    const Basis user = polarization_basis(sp);
    Shared sh;
    sh.basis = polarization_basis(internal);
    // The mirrors this point respects, and the group they generate.
    std::vector<Actions> actions;
    for (const Mirror& m : mirrors)
        if (auto a = mirror_actions(m, sp, sh.basis)) actions.push_back(std::move(*a));
    if (actions.empty()) return std::nullopt;
    const int k = static_cast<int>(actions.size());
    std::vector<Element> gE, gH, gA;
    for (int subset = 0; subset < (1 << k); ++subset) {
        Element e{identity_action(n2), {}}, h{identity_action(n2), {}}, a{identity_action(n2), {}};
        for (int m = 0; m < k; ++m)
            if (subset & (1 << m)) {
                e.action = compose(actions[m].E, e.action);
                h.action = compose(actions[m].H, h.action);
                a.action = compose(actions[m].A, a.action);
                e.mirrors.push_back(m), h.mirrors.push_back(m), a.mirrors.push_back(m);
            }
        gE.push_back(std::move(e)), gH.push_back(std::move(h)), gA.push_back(std::move(a));
    }
    StackSolution out;
    out.kz_superstrate = half_space_kz(sp.harmonics, sp.eps_superstrate);
    out.kz_substrate = half_space_kz(sp.harmonics, sp.eps_substrate);
    incident_fields(sp, user, out.kz_superstrate, sh.Finc, sh.Ginc);
    // The sectors, and which of them the asked incidence excites: those with a nonzero at
    // row i0 (s) or N + i0 (p) of the amplitude space where the incident waves asked for
    // have an s or p part in the sectors' basis (E and h along its s-hat).
    struct Sector {
        Columns E, H, A;
    };
    std::vector<Sector> sectors;
    const bool te = incidence != Incidence::P, tm = incidence != Incidence::S;
    const int i0 = sp.zero_order;
    // A part below round-off of the incident wave (s_direction(90 deg) = (-1, 6e-17)) is
    // no part: leaving it out changes the answer by as much.
    bool s_part = false, p_part = false;
    for (int c = 0; c < 2; ++c) {
        if ((c == 0 && !te) || (c == 1 && !tm)) continue;
        const double sx = sh.basis.sx[i0], sy = sh.basis.sy[i0];
        const cplx a_s = sx * sh.Finc(i0, c) + sy * sh.Finc(n + i0, c), a_p = sx * sh.Ginc(i0, c) + sy * sh.Ginc(n + i0, c);
        const double size = std::abs(a_s) + std::abs(a_p);
        s_part |= std::abs(a_s) > kNegligible * size;
        p_part |= std::abs(a_p) > kNegligible * size;
    }
    int total = 0;
    for (int s = 0; s < (1 << k); ++s) {
        std::vector<double> chi(k);
        for (int m = 0; m < k; ++m) chi[m] = (s & (1 << m)) ? -1.0 : 1.0;
        Sector sec{sector_columns(gE, chi, n2), sector_columns(gH, chi, n2), sector_columns(gA, chi, n2)};
        if (sec.E.size() != sec.A.size() || sec.H.size() != sec.A.size()) return std::nullopt;
        total += static_cast<int>(sec.A.size());
        bool excited = false;
        for (const auto& column : sec.A)
            for (const Entry& e : column) excited |= (s_part && e.row == i0) || (p_part && e.row == n + i0);
        if (excited && !sec.A.empty()) sectors.push_back(std::move(sec));
    }
    if (total != n2) return std::nullopt;

    outgoing_columns(sh.basis, out.kz_substrate, sp.eps_substrate, -1.0, sh.F, sh.G);
    sh.P.resize(pr.layers.size());
    sh.Q.resize(pr.layers.size());
    sh.uniform.resize(pr.layers.size());
    for (std::size_t l = 0; l < pr.layers.size(); ++l) {
        const LayerInput& in = pr.layers[l];
        if (in.kind == LayerKind::Uniform) {
            sh.uniform[l] = uniform_modes(sp.harmonics, in.eps);
        } else {
            const auto& M = in.matrices;
            pq_matrices(sp.harmonics, Z[l], M[1], M[2], M[3], M[4], sh.P[l], sh.Q[l]);
        }
    }
    Mat psi(n2, 2), phi(n2, 2);
    out.t = Mat(n2, 2);
    for (const Sector& sec : sectors) {
        std::vector<std::unique_ptr<LayerModes>> modes;
        std::vector<const LayerModes*> layers;
        for (std::size_t l = 0; l < pr.layers.size(); ++l) {
            if (sh.uniform[l])
                modes.push_back(std::make_unique<ReducedUniform>(*sh.uniform[l], sec.E, sec.H));
            else
                modes.push_back(reduced_general(sh.P[l], sh.Q[l], sec.E, sec.H));
            layers.push_back(modes.back().get());
        }
        const SectorSolution s = sector_etm(sp, sh, layers, sec.E, sec.H, sec.A, out.kz_superstrate);
        add(psi, expand(sec.E, s.psi, n2));
        add(phi, expand(sec.H, s.phi, n2));
        add(out.t, expand(sec.A, s.t, n2));
    }
    reflected_amplitudes(user, psi, phi, sh.Finc, sh.Ginc, out.r);
    to_user_basis(sh, user, out.t);
    const cplx not_solved(std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN());
    for (int i = 0; i < n2; ++i) {
        if (!te) out.r(i, 0) = out.t(i, 0) = not_solved;
        if (!tm) out.r(i, 1) = out.t(i, 1) = not_solved;
    }
    out.sectors_solved = static_cast<int>(sectors.size());
    out.sectors_total = 1 << k;
    return out;
}

}  // namespace rcwa
