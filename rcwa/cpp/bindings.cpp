// Python bindings of the RCWA core: types and array conversion only, no physics here.
//
// What crosses the boundary is typed: layers are LayerInput objects of a LayerKind (an
// enum: a kind that does not exist cannot be named), the stack method is a StackMethod,
// and results are StackSolution, SweepSolution and EigenDecomposition objects whose
// arrays are read-only numpy views of the core's own storage (no copy; each view keeps
// its result alive). The checks live in the core (make_layer, check_problem in
// sweep.hpp) and throw std::invalid_argument, which nanobind raises as ValueError. The
// GIL is released while the core computes. rcwa/_core.pyi is generated from this module
// by nanobind's stubgen (CMakeLists.txt).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/complex.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <stdexcept>
#include <string>

#include "complex_symmetric.hpp"
#include "efficiency.hpp"
#include "profile.hpp"
#include "sweep.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using rcwa::cplx;
using rcwa::Mat;

namespace {

using CArray2 = nb::ndarray<const cplx, nb::ndim<2>, nb::device::cpu>;
using RArray1 = nb::ndarray<const double, nb::ndim<1>, nb::device::cpu>;
// Read-only numpy views returned to Python.
using CView1 = nb::ndarray<nb::numpy, const cplx, nb::ndim<1>>;
using CView2 = nb::ndarray<nb::numpy, const cplx, nb::ndim<2>>;
using CView3 = nb::ndarray<nb::numpy, const cplx, nb::ndim<3>>;
using CArray2Out = nb::ndarray<nb::numpy, cplx, nb::ndim<2>>;

Mat to_mat(const CArray2& a) {
    // numpy's C order into the core's column order, tile by tile (a plain loop strides
    // through one of the two: 1 ms a matrix at 15 x 15 orders).
    constexpr int kTile = 32;
    const int rows = static_cast<int>(a.shape(0)), cols = static_cast<int>(a.shape(1));
    Mat m(rows, cols);
    auto v = a.view();
    for (int i0 = 0; i0 < rows; i0 += kTile)
        for (int j0 = 0; j0 < cols; j0 += kTile)
            for (int j = j0; j < std::min(j0 + kTile, cols); ++j)
                for (int i = i0; i < std::min(i0 + kTile, rows); ++i) m(i, j) = v(i, j);
    return m;
}

Mat to_square_mat(const CArray2& a, const char* what) {
    if (a.shape(0) != a.shape(1))
        throw std::invalid_argument(std::string(what) + ": expected a square matrix, got " +
                                    std::to_string(a.shape(0)) + " x " + std::to_string(a.shape(1)));
    return to_mat(a);
}

std::vector<double> to_vec(const RArray1& a) {
    std::vector<double> v(a.shape(0));
    auto view = a.view();
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = view(i);
    return v;
}

// A C-ordered copy (for LayerInput.matrices, which hands out what it was given).
CArray2Out copy_to_numpy(const Mat& m) {
    auto* data = new cplx[m.data.size()];
    for (int i = 0; i < m.rows; ++i)
        for (int j = 0; j < m.cols; ++j) data[static_cast<std::size_t>(i) * m.cols + j] = m(i, j);
    nb::capsule owner(data, [](void* p) noexcept { delete[] static_cast<cplx*>(p); });
    return CArray2Out(data, {static_cast<std::size_t>(m.rows), static_cast<std::size_t>(m.cols)}, owner);
}

// Owned (P, K, 2) or (K, 2) float64 arrays of an Efficiencies' R, T and into.
using RArrayOut = nb::ndarray<nb::numpy, double>;
RArrayOut owned(std::vector<double> values, std::vector<std::size_t> shape) {
    auto* data = new std::vector<double>(std::move(values));
    nb::capsule owner(data, [](void* p) noexcept { delete static_cast<std::vector<double>*>(p); });
    return RArrayOut(data->data(), shape.size(), shape.data(), owner);
}
std::tuple<RArrayOut, RArrayOut, RArrayOut> efficiency_arrays(rcwa::Efficiencies e, bool single) {
    std::vector<std::size_t> shape{e.kept, 2};
    if (!single) shape.insert(shape.begin(), e.points);
    return {owned(std::move(e.R), shape), owned(std::move(e.T), shape), owned(std::move(e.into), shape)};
}

// Views without an owner: returned from a property (rv_policy::reference_internal), the
// numpy array keeps the result object alive.
CView2 view(const Mat& m) {
    return CView2(m.ptr(), {static_cast<std::size_t>(m.rows), static_cast<std::size_t>(m.cols)}, nb::handle(),
                  {1, static_cast<int64_t>(m.rows)});  // column-major
}
CView1 view(const rcwa::CVec& v) { return CView1(v.data(), {v.size()}, nb::handle()); }

// The direction-independent part of a problem: harmonic offsets, media, layers. Checked
// by the core (check_problem) before it computes.
// A mirror as Python gives it: (axis, partner, phase), see rcwa::Mirror (sweep.hpp).
using MirrorTuple = std::tuple<int, std::vector<int>, std::vector<cplx>>;

std::vector<rcwa::Mirror> to_mirrors(const std::vector<MirrorTuple>& mirrors, std::size_t n) {
    std::vector<rcwa::Mirror> out;
    for (const auto& [axis, partner, phase] : mirrors) {
        if (axis != 0 && axis != 1) throw std::invalid_argument("mirrors: axis must be 0 (x) or 1 (y), got " + std::to_string(axis));
        if (partner.size() != n || phase.size() != n)
            throw std::invalid_argument("mirrors: partner and phase need one entry per harmonic (" + std::to_string(n) + ")");
        for (int j : partner)
            if (j < 0 || static_cast<std::size_t>(j) >= n)
                throw std::invalid_argument("mirrors: partner index " + std::to_string(j) + " outside [0, " +
                                            std::to_string(n) + ")");
        out.push_back(rcwa::Mirror{axis, partner, phase});
    }
    return out;
}

rcwa::SweepProblem base_problem(const RArray1& dkx, const RArray1& dky, int zero_order, cplx eps_sup,
                                cplx eps_sub, std::vector<rcwa::LayerInput> layers, rcwa::StackMethod method) {
    rcwa::SweepProblem pr;
    pr.dkx = to_vec(dkx);
    pr.dky = to_vec(dky);
    pr.zero_order = zero_order;
    pr.eps_superstrate = eps_sup;
    pr.eps_substrate = eps_sub;
    pr.method = method;
    pr.layers = std::move(layers);
    return pr;
}

// One solve: kx, ky are the harmonics themselves (offsets from a zero incident vector).
rcwa::StackSolution solve_stack_py(const RArray1& kx, const RArray1& ky, int zero_order, cplx eps_sup,
                                   cplx eps_sub, std::tuple<double, double> s_direction,
                                   std::vector<rcwa::LayerInput> layers, rcwa::StackMethod method,
                                   rcwa::Incidence incidence, bool fast_paths,
                                   const std::vector<MirrorTuple>& mirrors) {
    rcwa::SweepProblem pr = base_problem(kx, ky, zero_order, eps_sup, eps_sub, std::move(layers), method);
    pr.mirrors = to_mirrors(mirrors, pr.dkx.size());
    pr.kx0 = {0.0};
    pr.ky0 = {0.0};
    pr.s_x = {std::get<0>(s_direction)};
    pr.s_y = {std::get<1>(s_direction)};
    nb::gil_scoped_release release;
    return rcwa::solve_point(pr, 0, incidence, fast_paths);
}

rcwa::SweepResult sweep_py(const RArray1& dkx, const RArray1& dky, int zero_order, cplx eps_sup, cplx eps_sub,
                           std::vector<rcwa::LayerInput> layers, const RArray1& kx0, const RArray1& ky0,
                           const RArray1& s_x, const RArray1& s_y, const std::vector<int>& keep,
                           rcwa::StackMethod method, int threads, const std::vector<MirrorTuple>& mirrors) {
    rcwa::SweepProblem pr = base_problem(dkx, dky, zero_order, eps_sup, eps_sub, std::move(layers), method);
    pr.mirrors = to_mirrors(mirrors, pr.dkx.size());
    pr.kx0 = to_vec(kx0);
    pr.ky0 = to_vec(ky0);
    pr.s_x = to_vec(s_x);
    pr.s_y = to_vec(s_y);
    pr.keep = keep;
    pr.threads = threads;
    nb::gil_scoped_release release;
    return rcwa::sweep(pr);
}

// eig_from_guess (linalg.hpp), for tests: the decomposition, or None where it declines.
std::optional<rcwa::Eigen> eig_from_guess_py(const CArray2& A, const CArray2& guess) {
    const Mat a = to_square_mat(A, "A"), g = to_square_mat(guess, "guess");
    if (a.rows != g.rows)
        throw std::invalid_argument("guess: expected " + std::to_string(a.rows) + " x " + std::to_string(a.rows) +
                                    " (the size of A), got " + std::to_string(g.rows) + " x " + std::to_string(g.rows));
    nb::gil_scoped_release release;
    return rcwa::eig_from_guess(a, g);
}

// eig_complex_symmetric and eig_small (complex_symmetric.hpp, linalg.hpp), for tests and
// benchmarks: the decomposition, or None where the method declines.
std::optional<rcwa::Eigen> eig_complex_symmetric_py(const CArray2& A) {
    Mat a = to_square_mat(A, "A");
    nb::gil_scoped_release release;
    return rcwa::eig_complex_symmetric(std::move(a));
}
std::optional<rcwa::Eigen> eig_small_py(const CArray2& A) {
    Mat a = to_square_mat(A, "A");
    nb::gil_scoped_release release;
    return rcwa::eig_small(std::move(a));
}

void bind_layers(nb::module_& m) {
    nb::enum_<rcwa::LayerKind>(m, "LayerKind", "How a layer's modes are found, and so which matrices it carries.")
        .value("UNIFORM", rcwa::LayerKind::Uniform, "Homogeneous: modes in closed form, no matrices.")
        .value("LAMELLAR", rcwa::LayerKind::Lamellar,
               "1D grating (harmonics along x): matrices E, Exx; two N x N eigen-solves.")
        .value("GENERAL", rcwa::LayerKind::General,
               "2D or anisotropic: matrices E, Exx, Exy, Eyx, Eyy; one 2N x 2N eigen-solve.");

    nb::enum_<rcwa::StackMethod>(m, "StackMethod", "How the layers are combined (stack.hpp).")
        .value("ENHANCED_TRANSMITTANCE", rcwa::StackMethod::EnhancedTransmittance,
               "Moharam, Pommet, Grann & Gaylord 1995: one bottom-up sweep.")
        .value("SCATTERING_MATRIX", rcwa::StackMethod::ScatteringMatrix,
               "Redheffer star product of layer scattering matrices (Rumpf 2011).");

    nb::enum_<rcwa::Incidence>(m, "Incidence", "Which incident polarizations a single solve must answer.")
        .value("S", rcwa::Incidence::S, "s (TE) incidence only, where the stack decouples; else both.")
        .value("P", rcwa::Incidence::P, "p (TM) incidence only, where the stack decouples; else both.")
        .value("BOTH", rcwa::Incidence::Both, "Both polarizations.");

    nb::class_<rcwa::LayerInput>(m, "LayerInput",
                                 "One layer as the core receives it: its kind, its thickness times k0, the "
                                 "permittivity of a uniform layer, and the N x N Fourier matrices of a patterned "
                                 "one (lamellar: E, Exx, or E, [[1/eps]] with inverse_rule; general: E, Exx, Exy, "
                                 "Eyx, Eyy). Checked on construction (ValueError naming the field).")
        .def(
            "__init__",
            [](rcwa::LayerInput* self, rcwa::LayerKind kind, double k0_thickness, cplx permittivity,
               const std::vector<CArray2>& matrices, bool inverse_rule) {
                std::vector<Mat> mats;
                mats.reserve(matrices.size());
                for (const auto& a : matrices) mats.push_back(to_mat(a));
                new (self) rcwa::LayerInput(
                    rcwa::make_layer(kind, k0_thickness, permittivity, std::move(mats), inverse_rule));
            },
            "kind"_a, "k0_thickness"_a, "permittivity"_a = cplx(0.0, 0.0), "matrices"_a = std::vector<CArray2>(),
            "inverse_rule"_a = false)
        .def_ro("kind", &rcwa::LayerInput::kind)
        .def_ro("inverse_rule", &rcwa::LayerInput::inverse_rule,
                "A lamellar layer given as E and [[1/eps]] (Li's inverse rule): Exx = [[1/eps]]^-1 is formed in the "
                "core where a TM family needs it.")
        .def_ro("k0_thickness", &rcwa::LayerInput::thickness, "Thickness times k0 (radians of vacuum phase).")
        .def_ro("permittivity", &rcwa::LayerInput::eps, "Relative permittivity of a uniform layer.")
        .def_prop_ro("size", &rcwa::LayerInput::size, "N: the matrices are N x N (0 for a uniform layer).")
        .def_prop_ro(
            "matrices",
            [](const rcwa::LayerInput& layer) {
                std::vector<CArray2Out> out;
                for (const Mat& mat : layer.matrices) out.push_back(copy_to_numpy(mat));
                return out;
            },
            nb::rv_policy::automatic,  // owned copies, not views of the layer (reference_internal)
            "Copies of the Fourier matrices, in the order given.")
        .def_static(
            "lamellar",
            [](double k0_thickness, double period, const std::vector<std::tuple<double, double, cplx>>& segments,
               int harmonics, bool inverse_rule) {
                std::vector<rcwa::ProfileSegment> pieces;
                pieces.reserve(segments.size());
                for (const auto& [x0, x1, value] : segments) pieces.push_back({x0, x1, value});
                return rcwa::lamellar_layer(k0_thickness, period, pieces, harmonics, inverse_rule);
            },
            "k0_thickness"_a, "period"_a, "segments"_a, "harmonics"_a, "inverse_rule"_a = true,
            "A lamellar layer from its permittivity profile on [0, period), as (x0, x1, eps) segments: E = [[eps]] "
            "and [[1/eps]] (inverse_rule, Li 1996) or Exx = E (Laurent), for `harmonics` orders m = -M..M "
            "(profile.hpp).")
        .def("__repr__", [](const rcwa::LayerInput& layer) {
            return std::string("LayerInput(") + rcwa::kind_name(layer.kind) +
                   ", k0_thickness=" + std::to_string(layer.thickness) + ", N=" + std::to_string(layer.size()) + ")";
        });
}

void bind_results(nb::module_& m) {
    nb::class_<rcwa::StackSolution>(m, "StackSolution",
                                    "Outgoing amplitudes of one solve for unit s incidence (column 0) and unit p "
                                    "incidence (column 1). Row i is the s amplitude of harmonic i (E along s-hat), "
                                    "row N + i its p amplitude (h = Z0 H along s-hat).")
        .def_prop_ro("reflected", [](const rcwa::StackSolution& s) { return view(s.r); },
                     "Reflected amplitudes into the superstrate, (2N, 2).")
        .def_prop_ro("transmitted", [](const rcwa::StackSolution& s) { return view(s.t); },
                     "Transmitted amplitudes into the substrate, (2N, 2).")
        .def_prop_ro("kz_superstrate", [](const rcwa::StackSolution& s) { return view(s.kz_superstrate); },
                     "kz / k0 of each harmonic in the superstrate, outgoing branch, (N,).")
        .def_prop_ro("kz_substrate", [](const rcwa::StackSolution& s) { return view(s.kz_substrate); },
                     "kz / k0 of each harmonic in the substrate, outgoing branch, (N,).")
        .def(
            "efficiencies",
            [](const rcwa::StackSolution& s, int zero_order, cplx eps_sup, cplx eps_sub) {
                return efficiency_arrays(rcwa::efficiencies(s, zero_order, eps_sup, eps_sub), true);
            },
            "zero_order"_a, "eps_superstrate"_a, "eps_substrate"_a,
            "(R, T, into): each (N, 2), columns s and p incidence: the efficiencies of the harmonics and the power "
            "entering the substrate (T is zero over an absorbing one) per unit incident power (efficiency.hpp).")
        .def_ro("decoupled", &rcwa::StackSolution::decoupled,
                "Whether TE and TM were solved apart on N x N blocks (1D, every ky = 0: polarized.hpp); a "
                "polarization not asked for then has NaN amplitudes.")
        .def_ro("direct", &rcwa::StackSolution::direct,
                "Whether a one-layer stack was solved as one boundary system instead of through W^-1 and V^-1: "
                "4N x 4N (stack.cpp, solve_direct), or 2N x 2N per polarization in classical mount (polarized.cpp, "
                "solve_polarized_direct).")
        .def_ro("hermitian_solves", &rcwa::StackSolution::hermitian_solves,
                "Eigen-solves of lossless 1D layers done by Hermitian solvers (zheevd, zhegvd) instead of zgeev.")
        .def_ro("real_solves", &rcwa::StackSolution::real_solves,
                "Of hermitian_solves, those done in real arithmetic (dsyevd, dsygvd): the layer is symmetric about a "
                "point, and moving the origin there makes its matrices real (linalg.hpp, real_by_phase).")
        .def_ro("inverse_iteration_solves", &rcwa::StackSolution::inverse_iteration_solves,
                "Eigen-solves of lossy 1D layers (fewer than 75 harmonics) done by the QR algorithm for the "
                "eigenvalues and inverse iteration for the eigenvectors (linalg.hpp, eig_small) instead of zgeev.")
        .def_ro("complex_symmetric_solves", &rcwa::StackSolution::complex_symmetric_solves,
                "Eigen-solves of lossy 1D layers symmetric about a point done as complex symmetric problems: "
                "tridiagonal form by complex-orthogonal reflectors, QL, inverse iteration, one refinement step, "
                "accepted on a residual check (complex_symmetric.hpp) instead of eig_small or zgeev.")
        .def_ro("sectors_solved", &rcwa::StackSolution::sectors_solved,
                "Mirror-symmetry sectors solved (sectors.hpp), of sectors_total; 0 of 0 where none were used. A "
                "polarization not asked for then has NaN amplitudes.")
        .def_ro("sectors_total", &rcwa::StackSolution::sectors_total,
                "The number of mirror-symmetry sectors the point splits into (2 or 4), 0 where none were used.");

    nb::class_<rcwa::SweepResult>(m, "SweepSolution",
                                  "Amplitudes of the K kept harmonics at P incident directions, as StackSolution "
                                  "per point restricted to the kept rows (s rows, then p rows), and the work done.")
        .def_prop_ro("reflected", [](const rcwa::SweepResult& s) {
            return CView3(s.r.data(), {s.points, 2 * s.kept, 2}, nb::handle());
        }, "Reflected amplitudes, (P, 2K, 2).")
        .def_prop_ro("transmitted", [](const rcwa::SweepResult& s) {
            return CView3(s.t.data(), {s.points, 2 * s.kept, 2}, nb::handle());
        }, "Transmitted amplitudes, (P, 2K, 2).")
        .def_prop_ro("kz_superstrate", [](const rcwa::SweepResult& s) {
            return CView2(s.kz_superstrate.data(), {s.points, s.kept}, nb::handle());
        }, "kz / k0 of the kept harmonics in the superstrate, (P, K).")
        .def_prop_ro("kz_substrate", [](const rcwa::SweepResult& s) {
            return CView2(s.kz_substrate.data(), {s.points, s.kept}, nb::handle());
        }, "kz / k0 of the kept harmonics in the substrate, (P, K).")
        .def(
            "efficiencies",
            [](const rcwa::SweepResult& s, int zero_column, cplx eps_sup, cplx eps_sub) {
                return efficiency_arrays(rcwa::efficiencies(s, zero_column, eps_sup, eps_sub), false);
            },
            "zero_column"_a, "eps_superstrate"_a, "eps_substrate"_a,
            "(R, T, into): each (P, K, 2), as StackSolution.efficiencies per point; zero_column: the incident "
            "harmonic's column among the kept ones.")
        .def_ro("sector_points", &rcwa::SweepResult::sector_points,
                "Points solved in mirror-symmetry sectors (sectors.hpp): those at kx0 = 0 or ky0 = 0 of a mirror.")
        .def_ro("eigen_solves", &rcwa::SweepResult::eigen_solves,
                "Lamellar eigen-solves (two per 1D layer and group of points sharing kx0).")
        .def_ro("eigen_refined", &rcwa::SweepResult::eigen_refined,
                "Of the eigen-solves, those refined from a neighbouring kx0's eigenvectors.");

    nb::class_<rcwa::Eigen>(m, "EigenDecomposition", "A V = V diag(values), right eigenvectors as columns.")
        .def_prop_ro("values", [](const rcwa::Eigen& e) { return view(e.values); }, "Eigenvalues, (N,).")
        .def_prop_ro("vectors", [](const rcwa::Eigen& e) { return view(e.vectors); },
                     "Eigenvectors as columns, (N, N), each of unit norm.");
}

}  // namespace

NB_MODULE(_core, m) {
    m.doc() = "RCWA core (C++17, LAPACK from scipy-openblas32). See rcwa/cpp/*.hpp.";
    bind_layers(m);
    bind_results(m);
    m.def("solve_stack", &solve_stack_py, "kx"_a, "ky"_a, "zero_order"_a, "eps_superstrate"_a, "eps_substrate"_a,
          "s_direction"_a, "layers"_a, "method"_a = rcwa::StackMethod::EnhancedTransmittance,
          "incidence"_a = rcwa::Incidence::Both, "fast_paths"_a = true, "mirrors"_a = std::vector<MirrorTuple>(),
          "One solve. kx, ky: (N,) tangential wave vectors / k0 of the harmonics; zero_order: the index of the "
          "incident wave's; s_direction: s-hat where kx = ky = 0; layers from the superstrate down. incidence: the "
          "polarizations needed; fast_paths=False forces the general 2N x 2N path (for checking the fast ones). "
          "mirrors: the cell's mirrors as (axis, partner, phase) (sweep.hpp, Mirror), used where the point "
          "respects them (sectors.hpp).");
    m.def("sweep", &sweep_py, "dkx"_a, "dky"_a, "zero_order"_a, "eps_superstrate"_a, "eps_substrate"_a, "layers"_a,
          "kx0"_a, "ky0"_a, "s_x"_a, "s_y"_a, "keep"_a, "method"_a = rcwa::StackMethod::EnhancedTransmittance,
          "threads"_a = 1, "mirrors"_a = std::vector<MirrorTuple>(),
          "Many incident directions (P points) at one wavelength: harmonic i of point p has kx0[p] + dkx[i], "
          "ky0[p] + dky[i]; the harmonics listed in keep are returned. Points sharing kx0 share 1D eigen-solves; "
          "points respecting one of the mirrors (as in solve_stack) are solved in mirror-symmetry sectors.");
    m.def("eig_from_guess", &eig_from_guess_py, "A"_a, "guess"_a,
          "Eigen-decomposition of A refined from approximate eigenvectors, or None where it declines.");
    m.def("eig_complex_symmetric", &eig_complex_symmetric_py, "A"_a,
          "Eigen-decomposition of a complex symmetric A (complex_symmetric.hpp), or None where it breaks down or "
          "fails its residual check.");
    m.def("eig_small", &eig_small_py, "A"_a,
          "Eigen-decomposition by zhseqr and inverse iteration (linalg.hpp, eig_small), or None where it declines.");
    m.def("set_blas_threads", &rcwa::set_blas_threads, "n"_a,
          "Number of OpenBLAS threads (1 when the core runs its own threads).");
}
