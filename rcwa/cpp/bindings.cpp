// Python bindings of the RCWA core: array conversion only, no physics here.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/complex.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <stdexcept>
#include <string>

#include "sweep.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using rcwa::cplx;
using rcwa::Mat;

namespace {

using CArray2 = nb::ndarray<const std::complex<double>, nb::ndim<2>, nb::device::cpu>;
using RArray1 = nb::ndarray<const double, nb::ndim<1>, nb::device::cpu>;

Mat to_mat(const CArray2& a, int n, const char* what) {
    if (static_cast<int>(a.shape(0)) != n || static_cast<int>(a.shape(1)) != n)
        throw std::invalid_argument(std::string(what) + ": expected an N x N matrix, N = " + std::to_string(n));
    Mat m(n, n);
    auto v = a.view();
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) m(i, j) = v(i, j);
    return m;
}

std::vector<double> to_vec(const RArray1& a) {
    std::vector<double> v(a.shape(0));
    auto view = a.view();
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = view(i);
    return v;
}

nb::ndarray<nb::numpy, std::complex<double>, nb::ndim<2>> to_numpy(const Mat& m) {
    auto* data = new std::complex<double>[m.data.size()];
    for (int i = 0; i < m.rows; ++i)
        for (int j = 0; j < m.cols; ++j) data[static_cast<std::size_t>(i) * m.cols + j] = m(i, j);
    nb::capsule owner(data, [](void* p) noexcept { delete[] static_cast<std::complex<double>*>(p); });
    return nb::ndarray<nb::numpy, std::complex<double>, nb::ndim<2>>(
        data, {static_cast<std::size_t>(m.rows), static_cast<std::size_t>(m.cols)}, owner);
}

nb::ndarray<nb::numpy, std::complex<double>, nb::ndim<1>> to_numpy(const rcwa::CVec& v) {
    auto* data = new std::complex<double>[v.size()];
    std::copy(v.begin(), v.end(), data);
    nb::capsule owner(data, [](void* p) noexcept { delete[] static_cast<std::complex<double>*>(p); });
    return nb::ndarray<nb::numpy, std::complex<double>, nb::ndim<1>>(data, {v.size()}, owner);
}

using LayerTuple = std::tuple<std::string, double, cplx, std::vector<CArray2>>;

rcwa::StackMethod stack_method(const std::string& method) {
    if (method == "etm") return rcwa::StackMethod::EnhancedTransmittance;
    if (method == "smatrix") return rcwa::StackMethod::ScatteringMatrix;
    throw std::invalid_argument("method must be 'etm' or 'smatrix'");
}

// The direction-independent part of a problem: harmonic offsets, media, layers.
rcwa::SweepProblem base_problem(const RArray1& dkx, const RArray1& dky, int zero_order, cplx eps_sup,
                                cplx eps_sub, const std::vector<LayerTuple>& layers, const std::string& method) {
    rcwa::SweepProblem pr;
    pr.dkx = to_vec(dkx);
    pr.dky = to_vec(dky);
    const int n = static_cast<int>(pr.dkx.size());
    if (static_cast<int>(pr.dky.size()) != n) throw std::invalid_argument("kx and ky differ in length");
    if (zero_order < 0 || zero_order >= n) throw std::invalid_argument("zero_order out of range");
    pr.zero_order = zero_order;
    pr.eps_superstrate = eps_sup;
    pr.eps_substrate = eps_sub;
    pr.method = stack_method(method);
    for (const auto& [kind, d, eps, mats] : layers) {
        rcwa::LayerInput in{kind, d, eps, {}};
        const std::size_t need = kind == "uniform" ? 0 : kind == "lamellar" ? 2 : kind == "general" ? 5 : 99;
        if (need == 99) throw std::invalid_argument("unknown layer kind '" + kind + "'");
        if (mats.size() != need) throw std::invalid_argument("layer kind '" + kind + "' needs " + std::to_string(need) + " matrices");
        for (const auto& m : mats) in.matrices.push_back(to_mat(m, n, kind.c_str()));
        pr.layers.push_back(std::move(in));
    }
    return pr;
}

// One solve: kx, ky are the harmonics themselves (offsets from a zero incident vector).
nb::tuple solve_stack_py(const RArray1& kx, const RArray1& ky, int zero_order, cplx eps_sup, cplx eps_sub,
                         std::tuple<double, double> s_direction, const std::vector<LayerTuple>& layers,
                         const std::string& method) {
    rcwa::SweepProblem pr = base_problem(kx, ky, zero_order, eps_sup, eps_sub, layers, method);
    pr.kx0 = {0.0};
    pr.ky0 = {0.0};
    pr.s_x = {std::get<0>(s_direction)};
    pr.s_y = {std::get<1>(s_direction)};
    rcwa::StackSolution sol;
    {
        nb::gil_scoped_release release;
        sol = rcwa::solve_point(pr, 0);
    }
    return nb::make_tuple(to_numpy(sol.r), to_numpy(sol.t), to_numpy(sol.kz_superstrate),
                          to_numpy(sol.kz_substrate));
}

// Stack point-major results into one (P, rows, cols) array.
template <class Get>
nb::ndarray<nb::numpy, std::complex<double>> stack_points(std::size_t np, std::size_t rows, std::size_t cols, Get get) {
    auto* data = new std::complex<double>[np * rows * cols];
    for (std::size_t p = 0; p < np; ++p)
        for (std::size_t i = 0; i < rows; ++i)
            for (std::size_t j = 0; j < cols; ++j) data[(p * rows + i) * cols + j] = get(p, i, j);
    nb::capsule owner(data, [](void* q) noexcept { delete[] static_cast<std::complex<double>*>(q); });
    return nb::ndarray<nb::numpy, std::complex<double>>(data, {np, rows, cols}, owner);
}

nb::tuple sweep_py(const RArray1& dkx, const RArray1& dky, int zero_order, cplx eps_sup, cplx eps_sub,
                   const std::vector<LayerTuple>& layers, const RArray1& kx0, const RArray1& ky0,
                   const RArray1& s_x, const RArray1& s_y, const std::vector<int>& keep,
                   const std::string& method, int threads) {
    rcwa::SweepProblem pr = base_problem(dkx, dky, zero_order, eps_sup, eps_sub, layers, method);
    pr.kx0 = to_vec(kx0);
    pr.ky0 = to_vec(ky0);
    pr.s_x = to_vec(s_x);
    pr.s_y = to_vec(s_y);
    const std::size_t np = pr.kx0.size();
    if (pr.ky0.size() != np || pr.s_x.size() != np || pr.s_y.size() != np)
        throw std::invalid_argument("kx0, ky0, s_x and s_y must have one value per point");
    for (int k : keep)
        if (k < 0 || k >= static_cast<int>(pr.dkx.size())) throw std::invalid_argument("keep index out of range");
    pr.keep = keep;
    pr.threads = threads;
    rcwa::SweepResult res;
    {
        nb::gil_scoped_release release;
        res = rcwa::sweep(pr);
    }
    const std::size_t k = keep.size();
    auto r = stack_points(np, 2 * k, 2, [&](auto p, auto i, auto j) { return res.r[p](static_cast<int>(i), static_cast<int>(j)); });
    auto t = stack_points(np, 2 * k, 2, [&](auto p, auto i, auto j) { return res.t[p](static_cast<int>(i), static_cast<int>(j)); });
    auto kz1 = stack_points(np, k, 1, [&](auto p, auto i, auto) { return res.kz_superstrate[p][i]; });
    auto kz2 = stack_points(np, k, 1, [&](auto p, auto i, auto) { return res.kz_substrate[p][i]; });
    return nb::make_tuple(r, t, kz1, kz2, nb::make_tuple(res.eigen_solves, res.eigen_refined));
}

// eig_from_guess (linalg.hpp), for tests: (values, vectors), or None where it declines.
nb::object eig_from_guess_py(const CArray2& A, const CArray2& guess) {
    const int n = static_cast<int>(A.shape(0));
    const auto result = rcwa::eig_from_guess(to_mat(A, n, "A"), to_mat(guess, n, "guess"));
    if (!result) return nb::none();
    return nb::make_tuple(to_numpy(result->values), to_numpy(result->vectors));
}

}  // namespace

NB_MODULE(_core, m) {
    m.doc() = "RCWA core (C++17, LAPACK from scipy-openblas32). See rcwa/cpp/*.hpp.";
    m.def("solve_stack", &solve_stack_py, "kx"_a, "ky"_a, "zero_order"_a, "eps_superstrate"_a,
          "eps_substrate"_a, "s_direction"_a, "layers"_a, "method"_a = "etm",
          "Outgoing s/p amplitudes (r, t: 2N x 2 for unit s and p incidence) and the half-space kz.");
    m.def("sweep", &sweep_py, "dkx"_a, "dky"_a, "zero_order"_a, "eps_superstrate"_a, "eps_substrate"_a,
          "layers"_a, "kx0"_a, "ky0"_a, "s_x"_a, "s_y"_a, "keep"_a, "method"_a = "etm", "threads"_a = 1,
          "Amplitudes of the kept harmonics for many incident directions (P points): r, t of shape "
          "(P, 2K, 2) and kz of shape (P, K, 1); points sharing kx0 share 1D eigen-solves; and "
          "(lamellar eigen-solves, of which refined from a neighbouring kx0).");
    m.def("eig_from_guess", &eig_from_guess_py, "A"_a, "guess"_a,
          "Eigenvalues and eigenvectors of A refined from approximate eigenvectors, or None.");
    m.def("set_blas_threads", &rcwa::set_blas_threads, "n"_a,
          "Number of OpenBLAS threads (1 when the core runs its own threads).");
}
