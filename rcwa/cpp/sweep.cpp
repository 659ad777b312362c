#include "sweep.hpp"

#include <atomic>
#include <exception>
#include <map>
#include <mutex>
#include <thread>

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

// Per-kx0 work shared by the points of a group: the lamellar eigen-solves.
std::vector<std::unique_ptr<LamellarEigen>> shared_eigen(const SweepProblem& pr, const Harmonics& h) {
    std::vector<std::unique_ptr<LamellarEigen>> out(pr.layers.size());
    for (std::size_t k = 0; k < pr.layers.size(); ++k)
        if (pr.layers[k].kind == "lamellar")
            out[k] = std::make_unique<LamellarEigen>(lamellar_eigen(h.kx, pr.layers[k].matrices[0], pr.layers[k].matrices[1]));
    return out;
}

StackSolution solve_with(const SweepProblem& pr, std::size_t p, const std::vector<std::unique_ptr<LamellarEigen>>& eig) {
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

}  // namespace

StackSolution solve_point(const SweepProblem& pr, std::size_t p) {
    return solve_with(pr, p, shared_eigen(pr, harmonics_at(pr, pr.kx0[p], pr.ky0[p])));
}

SweepResult sweep(const SweepProblem& pr) {
    const std::size_t np = pr.kx0.size();
    SweepResult out;
    out.r.resize(np);
    out.t.resize(np);
    out.kz_superstrate.resize(np);
    out.kz_substrate.resize(np);
    std::map<double, std::vector<std::size_t>> by_kx;
    for (std::size_t p = 0; p < np; ++p) by_kx[pr.kx0[p]].push_back(p);
    std::vector<const std::vector<std::size_t>*> groups;
    for (const auto& [kx, points] : by_kx) groups.push_back(&points);

    std::atomic<std::size_t> next{0};
    std::exception_ptr failure;
    std::mutex failure_lock;
    auto worker = [&]() {
        try {
            for (std::size_t g = next++; g < groups.size(); g = next++) {
                const auto& points = *groups[g];
                const auto eig = shared_eigen(pr, harmonics_at(pr, pr.kx0[points[0]], pr.ky0[points[0]]));
                for (std::size_t p : points) keep_rows(pr, solve_with(pr, p, eig), out, p);
            }
        } catch (...) {
            std::lock_guard<std::mutex> lock(failure_lock);
            if (!failure) failure = std::current_exception();
            next = groups.size();
        }
    };
    const int nthreads = std::max(1, std::min<int>(pr.threads, static_cast<int>(groups.size())));
    std::vector<std::thread> pool;
    for (int i = 1; i < nthreads; ++i) pool.emplace_back(worker);
    worker();
    for (auto& th : pool) th.join();
    if (failure) std::rethrow_exception(failure);
    return out;
}

}  // namespace rcwa
