#include "sweep.hpp"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
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
// blocks below 1 MB on the heap and up to 16 MB of free heap top (process-wide, once).
void keep_freed_memory() {
#if defined(__GLIBC__)
    static std::once_flag once;
    std::call_once(once, [] {
        mallopt(M_MMAP_THRESHOLD, 1 << 20);
        mallopt(M_TRIM_THRESHOLD, 16 << 20);
    });
#endif
}

using SharedEigen = std::vector<std::unique_ptr<LamellarEigen>>;

// Z = E^-1 of every lamellar layer: it depends on the wavelength only.
std::vector<Mat> inverse_laurent(const SweepProblem& pr) {
    std::vector<Mat> out(pr.layers.size());
    for (std::size_t k = 0; k < pr.layers.size(); ++k)
        if (pr.layers[k].kind == "lamellar") out[k] = LU(pr.layers[k].matrices[0]).inverse();
    return out;
}

// Per-kx0 work shared by the points of a group: the lamellar eigen-solves, seeded by the
// previous group's (`near`, at a neighbouring kx0) where there is one.
SharedEigen shared_eigen(const SweepProblem& pr, const std::vector<Mat>& Z, const Harmonics& h, const SharedEigen* near) {
    SharedEigen out(pr.layers.size());
    for (std::size_t k = 0; k < pr.layers.size(); ++k)
        if (pr.layers[k].kind == "lamellar")
            out[k] = std::make_unique<LamellarEigen>(lamellar_eigen(
                h.kx, pr.layers[k].matrices[0], pr.layers[k].matrices[1], Z[k], near ? (*near)[k].get() : nullptr));
    return out;
}

StackSolution solve_with(const SweepProblem& pr, std::size_t p, const SharedEigen& eig) {
    StackProblem sp;
    sp.harmonics = harmonics_at(pr, pr.kx0[p], pr.ky0[p]);
    sp.zero_order = pr.zero_order;
    sp.eps_superstrate = pr.eps_superstrate;
    sp.eps_substrate = pr.eps_substrate;
    sp.s_x = pr.s_x[p];
    sp.s_y = pr.s_y[p];
    std::vector<std::unique_ptr<LayerModes>> modes;
    for (std::size_t k = 0; k < pr.layers.size(); ++k) {
        const LayerInput& in = pr.layers[k];
        if (in.kind == "uniform") {
            modes.push_back(uniform_modes(sp.harmonics, in.eps));
        } else if (in.kind == "lamellar") {
            modes.push_back(lamellar_modes(sp.harmonics.kx, *eig[k], sp.harmonics.ky[0]));
        } else {
            const auto& M = in.matrices;
            modes.push_back(general_modes(sp.harmonics, M[0], M[1], M[2], M[3], M[4]));
        }
        sp.layers.push_back(modes.back().get());
        sp.thickness.push_back(in.thickness);
    }
    return solve_stack(sp, pr.method);
}

void keep_rows(const SweepProblem& pr, const StackSolution& s, SweepResult& out, std::size_t p) {
    const int n = static_cast<int>(pr.dkx.size());
    const int k = static_cast<int>(pr.keep.size());
    Mat r(2 * k, 2), t(2 * k, 2);
    CVec kz1(k), kz2(k);
    for (int j = 0; j < k; ++j) {
        const int i = pr.keep[j];
        for (int c = 0; c < 2; ++c) {
            r(j, c) = s.r(i, c);
            r(k + j, c) = s.r(n + i, c);
            t(j, c) = s.t(i, c);
            t(k + j, c) = s.t(n + i, c);
        }
        kz1[j] = s.kz_superstrate[i];
        kz2[j] = s.kz_substrate[i];
    }
    out.r[p] = std::move(r);
    out.t[p] = std::move(t);
    out.kz_superstrate[p] = std::move(kz1);
    out.kz_substrate[p] = std::move(kz2);
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
// previous group's. Returns (lamellar eigen-solves, of which refined).
std::pair<std::size_t, std::size_t> solve_block(const SweepProblem& pr, const std::vector<Mat>& Z,
                                                const std::vector<std::vector<std::size_t>>& groups,
                                                std::size_t first, std::size_t last, SweepResult& out) {
    std::size_t solves = 0, refined = 0;
    SharedEigen previous;
    for (std::size_t g = first; g < last; ++g) {
        const auto& points = groups[g];
        SharedEigen eig = shared_eigen(pr, Z, harmonics_at(pr, pr.kx0[points[0]], pr.ky0[points[0]]),
                                       g > first ? &previous : nullptr);
        for (std::size_t p : points) keep_rows(pr, solve_with(pr, p, eig), out, p);
        for (const auto& layer : eig)
            if (layer) {
                solves += 2;
                refined += static_cast<std::size_t>(layer->refined);
            }
        previous = std::move(eig);
    }
    return {solves, refined};
}

}  // namespace

StackSolution solve_point(const SweepProblem& pr, std::size_t p) {
    keep_freed_memory();
    return solve_with(pr, p, shared_eigen(pr, inverse_laurent(pr), harmonics_at(pr, pr.kx0[p], pr.ky0[p]), nullptr));
}

SweepResult sweep(const SweepProblem& pr) {
    keep_freed_memory();
    const std::size_t np = pr.kx0.size();
    SweepResult out;
    out.r.resize(np);
    out.t.resize(np);
    out.kz_superstrate.resize(np);
    out.kz_substrate.resize(np);
    const std::vector<std::vector<std::size_t>> groups = groups_by_kx(pr.kx0);
    const std::vector<Mat> Z = inverse_laurent(pr);

    // Blocks of kBlock consecutive kx0: within a block each group's eigen-solve is seeded
    // by the one before, the next block starts afresh. The blocks do not depend on the
    // thread count, so neither do the results (bit for bit).
    constexpr std::size_t kBlock = 32;
    const std::size_t threads = static_cast<std::size_t>(std::max(1, pr.threads));
    const std::size_t blocks = (groups.size() + kBlock - 1) / kBlock;
    std::atomic<std::size_t> next{0}, solves{0}, refined{0};
    std::exception_ptr failure;
    std::mutex failure_lock;
    auto worker = [&]() {
        try {
            for (std::size_t b = next++; b < blocks; b = next++) {
                const auto [n_solves, n_refined] = solve_block(
                    pr, Z, groups, b * kBlock, std::min((b + 1) * kBlock, groups.size()), out);
                solves += n_solves;
                refined += n_refined;
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
    return out;
}

}  // namespace rcwa
