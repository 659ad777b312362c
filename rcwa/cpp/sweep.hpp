// Many solves of one structure at one wavelength: a sweep over incident directions.
#pragma once

#include <string>

#include "stack.hpp"

namespace rcwa {

// A layer as the sweep receives it: its Fourier matrices do not depend on the direction.
struct LayerInput {
    std::string kind;           // "uniform" | "lamellar" | "general"
    double thickness = 0.0;     // k0 * d
    cplx eps = 0.0;             // uniform layers
    std::vector<Mat> matrices;  // lamellar: E, Exx; general: E, Exx, Exy, Eyx, Eyy
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
};

// Amplitudes of the kept harmonics, point-major: r[p] is (2K x 2) as in StackSolution
// restricted to the kept rows (s rows first, then p rows); kz likewise (K per point).
struct SweepResult {
    std::vector<Mat> r, t;
    std::vector<CVec> kz_superstrate, kz_substrate;
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

// One point, the sweep's code path with full eigen-solves (used by single solves).
StackSolution solve_point(const SweepProblem& problem, std::size_t point);

}  // namespace rcwa
