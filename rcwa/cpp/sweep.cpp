#include "sweep.hpp"

#include "polarized.hpp"
#include "sectors.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace rcwa {

namespace {

Harmonics harmonics_at(const SweepProblem& pr, double kx0, double ky0) {
    Harmonics h;
    h.kx.resize(pr.dkx.size());
    h.ky.resize(pr.dky.size());
    for (std::size_t i = 0; i < pr.dkx.size(); ++i) {
        h.kx[i] = kx0 + pr.dkx[i];
        h.ky[i] = ky0 + pr.dky[i];
    }
    return h;
}

// A solve allocates and frees many 2N x 2N matrices (238 kB at N = 61). glibc at first
// serves blocks above 128 kB by mmap and hands freed heap tops back to the system, so each
// such matrix cost fresh zeroed pages: page faults took 15-20 % of a sweep's time. Keep
// blocks below 32 MB (glibc's largest threshold; 2N x 2N at 15 x 15 orders is 3.2 MB, and
// a single 2D solve there faulted in 29 MB of fresh pages, 3-6 % of its time) on the heap
// and up to 64 MB of free heap top (process-wide, once).
void keep_freed_memory() {
#if defined(__GLIBC__)
    static std::once_flag once;
    std::call_once(once, [] {
        mallopt(M_MMAP_THRESHOLD, 32 << 20);
        mallopt(M_TRIM_THRESHOLD, 64 << 20);
    });
#endif
}

using SharedEigen = std::vector<std::unique_ptr<LamellarEigen>>;

// The problem with every inverse_rule layer's Exx formed (exx_of): for the paths that
// need both families of every lamellar layer (conical mount, sweeps).
SweepProblem with_exx(const SweepProblem& pr) {
    SweepProblem out = pr;
    for (LayerInput& in : out.layers)
        if (in.inverse_rule) {
            in.matrices = SharedMatrices(std::vector<Mat>{in.matrices[0], exx_of(in)});
            in.inverse_rule = false;
        }
    return out;
}

// Z = E^-1 of every patterned layer: it depends on the wavelength only. Block by block
// in the sectors of the layers' mirrors where there are some (sectors.hpp).
std::vector<Mat> inverse_laurent(const SweepProblem& pr, const std::vector<Mirror>& mirrors = {}) {
    std::vector<Mat> out(pr.layers.size());
    for (std::size_t k = 0; k < pr.layers.size(); ++k) {
        if (pr.layers[k].kind == LayerKind::Lamellar) out[k] = LU(pr.layers[k].matrices[0]).inverse();
        if (pr.layers[k].kind == LayerKind::General) out[k] = laurent_inverse(pr.layers[k].matrices[0], mirrors);
    }
    return out;
}

// The general path's inverses where Zs was taken in the mirrors' sectors: each general layer's plain LU inverse
// again. The blocked inverse equals it only to round-off, which an ill-conditioned metal cell amplifies (1.4e-12 on
// the amplitudes of square gold pillars at 11 x 11 orders off the mirror planes); the general path then gives the same
// results with or without fast paths (3e-15). One extra N x N LU per general layer and wavelength.
std::vector<Mat> plain_inverses(const SweepProblem& pr, const std::vector<Mat>& Zs, const std::vector<Mirror>& mirrors) {
    std::vector<Mat> out = Zs;
    if (mirrors.empty()) return out;
    for (std::size_t k = 0; k < pr.layers.size(); ++k)
        if (pr.layers[k].kind == LayerKind::General) out[k] = LU(pr.layers[k].matrices[0]).inverse();
    return out;
}

// Per-kx0 work shared by the points of a group: the lamellar eigen-solves, seeded by the
// previous group's (`near`, at a neighbouring kx0) where there is one.
// `hermitian`: lossless layers may use Hermitian solvers (LamellarParts); single solves only.
// `inverses`: LamellarParts::inverses (false only where the stack is solved directly).
SharedEigen shared_eigen(const SweepProblem& pr, const std::vector<Mat>& Z, const Harmonics& h, const SharedEigen* near,
                         bool hermitian = false, bool inverses = true, bool complex_symmetric = false) {
    SharedEigen out(pr.layers.size());
    LamellarParts parts;
    parts.hermitian = hermitian;
    parts.inverses = inverses;
    parts.complex_symmetric = complex_symmetric;
    for (std::size_t k = 0; k < pr.layers.size(); ++k)
        if (pr.layers[k].kind == LayerKind::Lamellar)
            out[k] = std::make_unique<LamellarEigen>(lamellar_eigen(h.kx, pr.layers[k].matrices[0],
                                                                    pr.layers[k].matrices[1], Z[k],
                                                                    near ? (*near)[k].get() : nullptr, parts));
    return out;
}

// Point p's stack without its layers' modes (harmonics, media, s-hat, thicknesses).
StackProblem stack_problem(const SweepProblem& pr, std::size_t p) {
    StackProblem sp;
    sp.harmonics = harmonics_at(pr, pr.kx0[p], pr.ky0[p]);
    sp.zero_order = pr.zero_order;
    sp.eps_superstrate = pr.eps_superstrate;
    sp.eps_substrate = pr.eps_substrate;
    sp.s_x = pr.s_x[p];
    sp.s_y = pr.s_y[p];
    for (const LayerInput& in : pr.layers) sp.thickness.push_back(in.thickness);
    return sp;
}

bool decoupled_point(const SweepProblem& pr, const StackProblem& sp) {
    for (const LayerInput& in : pr.layers)
        if (in.kind == LayerKind::General) return false;
    return decouples(sp, pr.method);
}

// TE and TM apart (polarized.hpp), each only if asked for; one eigen-solve per lamellar
// layer and polarization, and Z = E^-1 only for TM.
StackSolution solve_decoupled(const SweepProblem& pr, const StackProblem& sp, Incidence incidence) {
    const bool te = incidence != Incidence::P, tm = incidence != Incidence::S;
    const int n = sp.harmonics.size();
    // One lamellar layer: solved directly (solve_polarized_direct), without its inverses.
    const bool direct = pr.layers.size() == 1 && pr.layers.front().kind == LayerKind::Lamellar;
    std::vector<PolarizedModes> te_layers, tm_layers;
    int hermitian_solves = 0, real_solves = 0, inverse_iteration_solves = 0, complex_symmetric_solves = 0;
    for (const LayerInput& in : pr.layers) {
        if (in.kind == LayerKind::Uniform) {
            if (te) te_layers.push_back(uniform_polarized(sp.harmonics.kx, in.eps, Polarization::TE));
            if (tm) tm_layers.push_back(uniform_polarized(sp.harmonics.kx, in.eps, Polarization::TM));
            continue;
        }
        const Mat Z = tm ? LU(in.matrices[0]).inverse() : Mat();
        // Li's rule: [[1/eps]] itself, its inverse Exx formed inside only where needed.
        const bool inverse_rule = tm && in.inverse_rule;
        const Mat Exx = tm && !inverse_rule ? exx_of(in) : Mat();
        const LamellarEigen e = lamellar_eigen(sp.harmonics.kx, in.matrices[0], Exx, Z, nullptr,
                                               LamellarParts{te, tm, false, true, !direct, true},
                                               inverse_rule ? &in.matrices[1] : nullptr);
        hermitian_solves += e.hermitian;
        real_solves += e.real;
        inverse_iteration_solves += e.inverse_iteration;
        complex_symmetric_solves += e.complex_symmetric;
        if (te) te_layers.push_back(lamellar_polarized(e, Polarization::TE));
        if (tm) tm_layers.push_back(lamellar_polarized(e, Polarization::TM));
    }
    StackSolution out;
    out.kz_superstrate = half_space_kz(sp.harmonics, sp.eps_superstrate);
    out.kz_substrate = half_space_kz(sp.harmonics, sp.eps_substrate);
    out.r = Mat(2 * n, 2);
    out.t = Mat(2 * n, 2);
    out.decoupled = true;
    out.hermitian_solves = hermitian_solves;
    out.real_solves = real_solves;
    out.inverse_iteration_solves = inverse_iteration_solves;
    out.complex_symmetric_solves = complex_symmetric_solves;
    const cplx not_solved(std::nan(""), std::nan(""));
    for (int i = 0; i < 2 * n; ++i) {
        if (!te) out.r(i, 0) = out.t(i, 0) = not_solved;
        if (!tm) out.r(i, 1) = out.t(i, 1) = not_solved;
    }
    out.direct = direct;
    if (direct) {
        if (te) solve_polarized_direct(sp, Polarization::TE, te_layers.front(), out);
        if (tm) solve_polarized_direct(sp, Polarization::TM, tm_layers.front(), out);
        return out;
    }
    if (te) solve_polarized(sp, Polarization::TE, te_layers, out);
    if (tm) solve_polarized(sp, Polarization::TM, tm_layers, out);
    return out;
}

// `mirrors`: those every layer respects (respected_mirrors), tried first (sectors.hpp).
// Z: inverse_laurent. `direct`: a one-layer stack of a general layer is solved directly
// (stack.hpp, direct_single_layer).
// Zs: the sectors' inverses (inverse_laurent with the mirrors), where they differ from Z.
StackSolution solve_with(const SweepProblem& pr, std::size_t p, const SharedEigen& eig, const std::vector<Mat>& Z,
                         const std::vector<Mirror>& mirrors = {}, bool direct = true,
                         const std::vector<Mat>* Zs = nullptr) {
    StackProblem sp = stack_problem(pr, p);
    sp.direct_single_layer = direct;
    if (!mirrors.empty())
        if (auto sectors = solve_sectors(pr, sp, mirrors, Incidence::Both, Zs ? *Zs : Z)) return std::move(*sectors);
    std::vector<std::unique_ptr<LayerModes>> modes;
    for (std::size_t k = 0; k < pr.layers.size(); ++k) {
        const LayerInput& in = pr.layers[k];
        if (in.kind == LayerKind::Uniform) {
            modes.push_back(uniform_modes(sp.harmonics, in.eps));
        } else if (in.kind == LayerKind::Lamellar) {
            modes.push_back(lamellar_modes(sp.harmonics.kx, *eig[k], sp.harmonics.ky[0]));
        } else {
            const auto& M = in.matrices;
            modes.push_back(general_modes(sp.harmonics, Z[k], M[1], M[2], M[3], M[4]));
        }
        sp.layers.push_back(modes.back().get());
    }
    return solve_stack(sp, pr.method);
}

// The kept rows of point p's solution into the sweep's (P, 2K, 2) and (P, K) arrays.
void keep_rows(const SweepProblem& pr, const StackSolution& s, SweepResult& out, std::size_t p) {
    const int n = static_cast<int>(pr.dkx.size());
    const std::size_t k = pr.keep.size();
    cplx* r = out.r.data() + p * 4 * k;
    cplx* t = out.t.data() + p * 4 * k;
    for (std::size_t j = 0; j < k; ++j) {
        const int i = pr.keep[j];
        for (int c = 0; c < 2; ++c) {
            r[2 * j + c] = s.r(i, c);
            r[2 * (k + j) + c] = s.r(n + i, c);
            t[2 * j + c] = s.t(i, c);
            t[2 * (k + j) + c] = s.t(n + i, c);
        }
        out.kz_superstrate[p * k + j] = s.kz_superstrate[i];
        out.kz_substrate[p * k + j] = s.kz_substrate[i];
    }
}

// Points grouped by kx0, in increasing kx0. Values within kSameKx of the group's first
// count as equal: sin(theta) cos(phi) of different grid directions often lands on the
// same value give or take an ulp (about 40 % of the paper grid's distinct kx0), and a
// 1e-13 shift of kx changes the eigenvectors far below the solver's round-off.
std::vector<std::vector<std::size_t>> groups_by_kx(const std::vector<double>& kx0) {
    constexpr double kSameKx = 1e-13;
    std::vector<std::size_t> order(kx0.size());
    for (std::size_t p = 0; p < order.size(); ++p) order[p] = p;
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return kx0[a] < kx0[b]; });
    std::vector<std::vector<std::size_t>> groups;
    for (std::size_t p : order) {
        if (groups.empty() || kx0[p] - kx0[groups.back().front()] > kSameKx) groups.emplace_back();
        groups.back().push_back(p);
    }
    return groups;
}

// Groups [first, last) of neighbouring kx0, each group's eigen-solves seeded by the
// previous group's. Returns the lamellar eigen-solves, of which refined, and the points
// solved in mirror sectors.
struct BlockWork {
    std::size_t solves = 0, refined = 0, sectors = 0;
};

BlockWork solve_block(const SweepProblem& pr, const std::vector<Mat>& Z, const std::vector<Mat>& Zs,
                      const std::vector<Mirror>& mirrors, const std::vector<std::vector<std::size_t>>& groups,
                      std::size_t first, std::size_t last, SweepResult& out) {
    std::size_t solves = 0, refined = 0, sectors = 0;
    SharedEigen previous;
    for (std::size_t g = first; g < last; ++g) {
        const auto& points = groups[g];
        // Not the complex-symmetric path (LamellarParts::complex_symmetric): on the CD's paper
        // grid (2 deg steps, 61 orders) it made the sweep only 10 % faster than the neighbour's
        // refinement (eig_from_guess) that it replaces.
        SharedEigen eig = shared_eigen(pr, Z, harmonics_at(pr, pr.kx0[points[0]], pr.ky0[points[0]]),
                                       g > first ? &previous : nullptr);
        for (std::size_t p : points) {
            const StackSolution s = solve_with(pr, p, eig, Z, mirrors, true, &Zs);
            if (s.sectors_total > 0) ++sectors;
            keep_rows(pr, s, out, p);
        }
        for (const auto& layer : eig)
            if (layer) {
                solves += 2;
                refined += static_cast<std::size_t>(layer->refined);
            }
        previous = std::move(eig);
    }
    return {solves, refined, sectors};
}

}  // namespace

std::size_t matrix_count(LayerKind kind) {
    switch (kind) {
        case LayerKind::Uniform: return 0;
        case LayerKind::Lamellar: return 2;
        case LayerKind::General: return 5;
    }
    throw std::invalid_argument("unknown layer kind");
}

const char* kind_name(LayerKind kind) {
    switch (kind) {
        case LayerKind::Uniform: return "uniform";
        case LayerKind::Lamellar: return "lamellar";
        case LayerKind::General: return "general";
    }
    throw std::invalid_argument("unknown layer kind");
}

LayerInput make_layer(LayerKind kind, double thickness, cplx eps, std::vector<Mat> matrices, bool inverse_rule) {
    const std::string what = std::string(kind_name(kind)) + " layer: ";
    if (inverse_rule && kind != LayerKind::Lamellar)
        throw std::invalid_argument(what + "inverse_rule applies to lamellar layers only");
    if (!std::isfinite(thickness) || thickness < 0.0)
        throw std::invalid_argument(what + "k0_thickness must be finite and >= 0, got " + std::to_string(thickness));
    if (!std::isfinite(eps.real()) || !std::isfinite(eps.imag()))
        throw std::invalid_argument(what + "permittivity must be finite");
    const std::size_t need = matrix_count(kind);
    if (matrices.size() != need)
        throw std::invalid_argument(what + "matrices: expected " + std::to_string(need) + ", got " +
                                    std::to_string(matrices.size()));
    for (std::size_t i = 0; i < matrices.size(); ++i) {
        const Mat& m = matrices[i];
        if (m.rows < 1 || m.rows != m.cols || m.rows != matrices.front().rows)
            throw std::invalid_argument(what + "matrices[" + std::to_string(i) + "]: expected shape (N, N) with N = " +
                                        std::to_string(matrices.front().rows) + ", got (" + std::to_string(m.rows) +
                                        ", " + std::to_string(m.cols) + ")");
    }
    return LayerInput{kind, thickness, eps, std::move(matrices), inverse_rule};
}

Mat exx_of(const LayerInput& layer) {
    if (layer.kind != LayerKind::Lamellar) throw std::invalid_argument("exx_of: not a lamellar layer");
    return layer.inverse_rule ? LU(layer.matrices[1]).inverse() : layer.matrices[1];
}

void check_problem(const SweepProblem& pr) {
    const std::size_t n = pr.dkx.size();
    if (n == 0 || pr.dky.size() != n)
        throw std::invalid_argument("harmonics: kx and ky must be non-empty and of one length, got " +
                                    std::to_string(n) + " and " + std::to_string(pr.dky.size()));
    if (pr.zero_order < 0 || static_cast<std::size_t>(pr.zero_order) >= n)
        throw std::invalid_argument("zero_order: expected an index in [0, " + std::to_string(n) + "), got " +
                                    std::to_string(pr.zero_order));
    for (std::size_t k = 0; k < pr.layers.size(); ++k) {
        const LayerInput& in = pr.layers[k];
        if (in.kind != LayerKind::Uniform && static_cast<std::size_t>(in.size()) != n)
            throw std::invalid_argument("layers[" + std::to_string(k) + "] (" + kind_name(in.kind) +
                                        "): matrices are " + std::to_string(in.size()) + " x " +
                                        std::to_string(in.size()) + ", expected " + std::to_string(n) + " x " +
                                        std::to_string(n) + " (one row per harmonic)");
    }
    const std::size_t np = pr.kx0.size();
    if (pr.ky0.size() != np || pr.s_x.size() != np || pr.s_y.size() != np)
        throw std::invalid_argument("kx0, ky0, s_x and s_y must have one value per point");
    for (int i : pr.keep)
        if (i < 0 || static_cast<std::size_t>(i) >= n)
            throw std::invalid_argument("keep: index " + std::to_string(i) + " outside [0, " + std::to_string(n) + ")");
}

StackSolution solve_point(const SweepProblem& input, std::size_t p, Incidence incidence, bool fast_paths) {
    check_problem(input);
    if (p >= input.kx0.size()) throw std::invalid_argument("point " + std::to_string(p) + " outside the problem's points");
    keep_freed_memory();
    if (fast_paths) {
        const StackProblem sp = stack_problem(input, p);
        if (decoupled_point(input, sp)) return solve_decoupled(input, sp, incidence);
    }
    const SweepProblem pr = with_exx(input);
    std::vector<Mirror> mirrors;
    if (fast_paths) mirrors = respected_mirrors(pr, stack_problem(pr, p));
    const std::vector<Mat> Zs = inverse_laurent(pr, mirrors);
    if (!mirrors.empty())
        if (auto sectors = solve_sectors(pr, stack_problem(pr, p), mirrors, incidence, Zs)) return std::move(*sectors);
    const std::vector<Mat> Z = plain_inverses(pr, Zs, mirrors);
    // A single lamellar layer (1D, conical) is solved directly, without its inverses' blocks
    // (stack.cpp, solve_direct): 4N x 4N LU instead of the ETM step's and the blocks' work.
    const bool direct_lamellar = fast_paths && pr.method == StackMethod::EnhancedTransmittance &&
                                 pr.layers.size() == 1 && pr.layers.front().kind == LayerKind::Lamellar;
    const SharedEigen eig =
        shared_eigen(pr, Z, harmonics_at(pr, pr.kx0[p], pr.ky0[p]), nullptr, fast_paths, !direct_lamellar, fast_paths);
    StackSolution out = solve_with(pr, p, eig, Z, {}, fast_paths);  // no sectors: fast_paths is false, or none applies
    for (const auto& layer : eig)
        if (layer) {
            out.hermitian_solves += layer->hermitian;
            out.real_solves += layer->real;
            out.inverse_iteration_solves += layer->inverse_iteration;
            out.complex_symmetric_solves += layer->complex_symmetric;
        }
    return out;
}

SweepResult sweep(const SweepProblem& input) {
    check_problem(input);
    const SweepProblem pr = with_exx(input);
    keep_freed_memory();
    const std::size_t np = pr.kx0.size();
    SweepResult out;
    out.points = np;
    out.kept = pr.keep.size();
    out.r.resize(np * 4 * out.kept);
    out.t.resize(np * 4 * out.kept);
    out.kz_superstrate.resize(np * out.kept);
    out.kz_substrate.resize(np * out.kept);
    const std::vector<std::vector<std::size_t>> groups = groups_by_kx(pr.kx0);
    const std::vector<Mirror> mirrors = respected_mirrors(pr);
    const std::vector<Mat> Zs = inverse_laurent(pr, mirrors);
    const std::vector<Mat> Z = plain_inverses(pr, Zs, mirrors);

    // Blocks of kBlock consecutive kx0: within a block each group's eigen-solve is seeded
    // by the one before, the next block starts afresh. The blocks do not depend on the
    // thread count, so neither do the results (bit for bit).
    constexpr std::size_t kBlock = 32;
    const std::size_t threads = static_cast<std::size_t>(std::max(1, pr.threads));
    const std::size_t blocks = (groups.size() + kBlock - 1) / kBlock;
    std::atomic<std::size_t> next{0}, solves{0}, refined{0}, sectors{0};
    std::exception_ptr failure;
    std::mutex failure_lock;
    auto worker = [&]() {
        try {
            for (std::size_t b = next++; b < blocks; b = next++) {
                const BlockWork work = solve_block(pr, Z, Zs, mirrors, groups, b * kBlock, std::min((b + 1) * kBlock, groups.size()), out);
                solves += work.solves;
                refined += work.refined;
                sectors += work.sectors;
            }
        } catch (...) {
            std::lock_guard<std::mutex> lock(failure_lock);
            if (!failure) failure = std::current_exception();
            next = blocks;
        }
    };
    const int nthreads = static_cast<int>(std::min(threads, std::max<std::size_t>(1, blocks)));
    std::vector<std::thread> pool;
    for (int i = 1; i < nthreads; ++i) pool.emplace_back(worker);
    worker();
    for (auto& th : pool) th.join();
    if (failure) std::rethrow_exception(failure);
    out.eigen_solves = solves;
    out.eigen_refined = refined;
    out.sector_points = sectors;
    return out;
}

}  // namespace rcwa
