// Python bindings of the RCWA core: array conversion only, no physics here.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/complex.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <stdexcept>
#include <string>

#include "stack.hpp"

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

struct LayerInput {
    std::string kind;  // "uniform" | "lamellar" | "general"
    double thickness;  // k0 * d
    cplx eps;          // uniform layers
    std::vector<Mat> matrices;  // lamellar: E, Exx; general: E, Exx, Exy, Eyx, Eyy
};

// kx, ky: normalized harmonics; layers: (kind, k0*d, eps, [matrices]) from the top down.
nb::tuple solve_stack_py(const RArray1& kx, const RArray1& ky, int zero_order, cplx eps_sup,
                         cplx eps_sub, std::tuple<double, double> s_direction,
                         const std::vector<std::tuple<std::string, double, cplx, std::vector<CArray2>>>& layers,
                         const std::string& method) {
    if (method != "smatrix" && method != "etm") throw std::invalid_argument("method must be 'smatrix' or 'etm'");
    rcwa::StackProblem pr;
    pr.harmonics.kx = to_vec(kx);
    pr.harmonics.ky = to_vec(ky);
    const int n = pr.harmonics.size();
    if (static_cast<int>(pr.harmonics.ky.size()) != n) throw std::invalid_argument("kx and ky differ in length");
    if (zero_order < 0 || zero_order >= n) throw std::invalid_argument("zero_order out of range");
    pr.zero_order = zero_order;
    pr.eps_superstrate = eps_sup;
    pr.eps_substrate = eps_sub;
    pr.s_x = std::get<0>(s_direction);
    pr.s_y = std::get<1>(s_direction);

    std::vector<LayerInput> inputs;
    for (const auto& [kind, d, eps, mats] : layers) {
        LayerInput in{kind, d, eps, {}};
        const std::size_t need = kind == "uniform" ? 0 : kind == "lamellar" ? 2 : kind == "general" ? 5 : 99;
        if (need == 99) throw std::invalid_argument("unknown layer kind '" + kind + "'");
        if (mats.size() != need) throw std::invalid_argument("layer kind '" + kind + "' needs " + std::to_string(need) + " matrices");
        for (const auto& m : mats) in.matrices.push_back(to_mat(m, n, kind.c_str()));
        inputs.push_back(std::move(in));
    }

    rcwa::StackSolution sol;
    {
        nb::gil_scoped_release release;
        std::vector<std::unique_ptr<rcwa::LayerModes>> modes;
        for (const auto& in : inputs) {
            if (in.kind == "uniform") {
                modes.push_back(rcwa::uniform_modes(pr.harmonics, in.eps));
            } else if (in.kind == "lamellar") {
                const auto e = rcwa::lamellar_eigen(pr.harmonics.kx, in.matrices[0], in.matrices[1]);
                modes.push_back(rcwa::lamellar_modes(pr.harmonics.kx, e, pr.harmonics.ky[0]));
            } else {
                const auto& M = in.matrices;
                modes.push_back(rcwa::general_modes(pr.harmonics, M[0], M[1], M[2], M[3], M[4]));
            }
            pr.layers.push_back(modes.back().get());
            pr.thickness.push_back(in.thickness);
        }
        sol = rcwa::solve_stack(pr, method == "etm" ? rcwa::StackMethod::EnhancedTransmittance
                                                    : rcwa::StackMethod::ScatteringMatrix);
    }
    return nb::make_tuple(to_numpy(sol.r), to_numpy(sol.t), to_numpy(sol.kz_superstrate),
                          to_numpy(sol.kz_substrate));
}

}  // namespace

NB_MODULE(_core, m) {
    m.doc() = "RCWA core (C++17, LAPACK from scipy-openblas32). See rcwa/cpp/*.hpp.";
    m.def("solve_stack", &solve_stack_py, "kx"_a, "ky"_a, "zero_order"_a, "eps_superstrate"_a,
          "eps_substrate"_a, "s_direction"_a, "layers"_a, "method"_a = "etm",
          "Outgoing s/p amplitudes (r, t: 2N x 2 for unit s and p incidence) and the half-space kz.");
    m.def("set_blas_threads", &rcwa::set_blas_threads, "n"_a,
          "Number of OpenBLAS threads (1 when the core runs its own threads).");
}
