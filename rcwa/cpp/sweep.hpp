// Many solves of one structure at one wavelength: a sweep over incident directions.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include "stack.hpp"

namespace rcwa {

// How a layer's modes are found (modes.hpp), and so which matrices it carries.
enum class LayerKind {
    Uniform,   // homogeneous: modes in closed form, no matrices (uses `eps`)
    Lamellar,  // 1D grating, harmonics along x: E, Exx (two N x N eigen-solves)
    General,   // 2D or anisotropic: E, Exx, Exy, Eyx, Eyy (one 2N x 2N eigen-solve of PQ)
};

// How many N x N Fourier matrices a layer of this kind carries (0, 2 or 5).
std::size_t matrix_count(LayerKind kind);
const char* kind_name(LayerKind kind);  // "uniform", "lamellar", "general" (for messages)

// A layer as the sweep receives it: its Fourier matrices do not depend on the direction.
// Built by make_layer, which checks it; the harmonic count is checked against the
// problem's in check_problem.
// A layer's Fourier matrices, immutable and shared: copying a LayerInput (the bindings
// receive the layers by value on every call) copies no matrix (5 x 0.8 MB at 15 x 15 orders).
class SharedMatrices {
  public:
    SharedMatrices() = default;
    SharedMatrices(std::vector<Mat> matrices)  // NOLINT: implicit, as the vector it holds
        : p_(std::make_shared<const std::vector<Mat>>(std::move(matrices))) {}
    const Mat& operator[](std::size_t i) const { return all()[i]; }
    const Mat& front() const { return all().front(); }
    std::size_t size() const { return all().size(); }
    bool empty() const { return all().empty(); }
    std::vector<Mat>::const_iterator begin() const { return all().begin(); }
    std::vector<Mat>::const_iterator end() const { return all().end(); }

  private:
    const std::vector<Mat>& all() const {
        static const std::vector<Mat> none;
        return p_ ? *p_ : none;
    }
    std::shared_ptr<const std::vector<Mat>> p_;
};

struct LayerInput {
    LayerKind kind = LayerKind::Uniform;
    double thickness = 0.0;   // k0 * d
    cplx eps = 0.0;           // uniform layers
    SharedMatrices matrices;  // lamellar: E, Exx (or [[1/eps]]: inverse_rule); general: E, Exx, Exy, Eyx, Eyy
    // A lamellar layer by Li's inverse rule given as E and [[1/eps]]: Exx = [[1/eps]]^-1 is
    // formed where a TM family needs it (exx_of), not before: a request for s in classical
    // mount never does, and the inverse costs a fifth of the TE eigen-solve at N = 61.
    bool inverse_rule = false;
    int size() const { return matrices.empty() ? 0 : matrices.front().rows; }
};

// A checked LayerInput: throws std::invalid_argument (naming what is wrong) for a
// negative or non-finite thickness, a non-finite permittivity, the wrong number of
// matrices for the kind, matrices that are not square and of one size, or inverse_rule
// on a layer that is not lamellar.
LayerInput make_layer(LayerKind kind, double thickness, cplx eps, std::vector<Mat> matrices, bool inverse_rule = false);
// A lamellar layer's Exx: matrices[1], or its inverse for an inverse_rule layer.
Mat exx_of(const LayerInput& layer);

// A mirror of the cell: x -> 2c - x (axis 0) or y -> 2c - y (axis 1). For a scalar field
// f with harmonics f_i (at kx0 = 0, resp. ky0 = 0), the mirrored field has
// (S f)_{partner[i]} = phase[i] f_i, phase[i] = exp(2 i k0 kx_i c) (resp. ky_i).
// Used by the mirror-sector solve (sectors.hpp) at the points that respect it.
struct Mirror {
    int axis = 0;
    std::vector<int> partner;
    CVec phase;
};

struct SweepProblem {
    std::vector<double> dkx, dky;   // harmonic offsets: kx_i = kx0 + dkx_i, ky_i = ky0 + dky_i
    int zero_order = 0;
    cplx eps_superstrate, eps_substrate;
    std::vector<LayerInput> layers;
    std::vector<double> kx0, ky0;   // the incident tangential wave vectors (one per point)
    std::vector<double> s_x, s_y;   // s direction per point (used at normal incidence)
    std::vector<int> keep;          // harmonics whose amplitudes are returned
    StackMethod method = StackMethod::EnhancedTransmittance;
    int threads = 1;
    std::vector<Mirror> mirrors;    // the cell's mirrors; empty: no sector solves
};

// Throws std::invalid_argument unless the arrays of `problem` agree: dkx and dky of one
// length N, zero_order in [0, N), every layer's matrices N x N, one kx0, ky0, s_x, s_y
// per point, keep indices in [0, N).
void check_problem(const SweepProblem& problem);

// Amplitudes of the kept harmonics (K = keep.size()) at P points, point-major and
// row-major: r is (P, 2K, 2), the point's StackSolution r restricted to the kept rows (s
// rows first, then p rows), r[(p * 2K + row) * 2 + column]; t likewise; kz (P, K).
struct SweepResult {
    std::size_t points = 0, kept = 0;
    CVec r, t;
    CVec kz_superstrate, kz_substrate;
    std::size_t sector_points = 0;   // points solved in mirror-symmetry sectors (sectors.hpp)
    std::size_t eigen_solves = 0;    // lamellar eigen-solves (two per layer and kx0 group)
    std::size_t eigen_refined = 0;   // of which refined from a neighbour's eigenvectors
};

// Points that share kx0 (to 1e-13) share every 1D lamellar layer's eigen-solve (its
// eigenvectors do not depend on ky: lamellar.cpp), so points are grouped by kx0. The
// groups, sorted by kx0, are cut into blocks of neighbours spread over `threads`
// std::threads; inside a block each eigen-solve is refined from the previous group's
// eigenvectors (linalg.hpp, eig_from_guess), a few matrix products instead of a full
// solve, with the full solve as fallback.
SweepResult sweep(const SweepProblem& problem);

// Which incident polarizations a single solve must answer.
enum class Incidence { S, P, Both };

// One point, the sweep's code path with full eigen-solves (used by single solves).
// Where `fast_paths` and the point respects a mirror of `problem.mirrors` (a 2D stack
// at kx0 = 0 or ky0 = 0: sectors.hpp), it is solved in the mirror-symmetry sectors the
// asked `incidence` excites (the other column NaN); the sweep does the same for both
// polarizations.
// Both check the problem first (check_problem). Where the point decouples (a 1D stack of
// uniform and lamellar layers with every ky = 0, ETM: polarized.hpp) and `fast_paths`, TE
// and TM are solved apart on N x N blocks, and only those `incidence` asks for: the other
// column of r and t is NaN. Otherwise both columns are solved, as in the sweep.
StackSolution solve_point(const SweepProblem& problem, std::size_t point, Incidence incidence = Incidence::Both,
                          bool fast_paths = true);

}  // namespace rcwa
