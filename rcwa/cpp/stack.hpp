// Reflection and transmission of a layer stack between two half-spaces.
#pragma once

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
    int hermitian_solves = 0;  // eigen-solves done by Hermitian solvers (lossless layers: LamellarParts)
};

// kz of every harmonic in a half-space of permittivity eps, outgoing branch (outgoing_sqrt).
CVec half_space_kz(const Harmonics& h, cplx eps);

enum class StackMethod {
    // Redheffer star product of layer scattering matrices (Redheffer 1961; Rumpf 2011,
    // PIER B 35, 241, Eqs. 60-73; as in S4, Liu & Fan 2012). Gives both sides of the stack.
    ScatteringMatrix,
    // Enhanced transmittance matrix (Moharam, Pommet, Grann & Gaylord 1995, JOSA A 12,
    // 1077): one bottom-up sweep, about half the work for a one-sided solve.
    EnhancedTransmittance,
};

StackSolution solve_stack(const StackProblem& problem, StackMethod method = StackMethod::EnhancedTransmittance);

}  // namespace rcwa
