// Diffraction efficiencies from a solve's outgoing amplitudes: the power each order carries
// through a plane z = const per unit incident power, for single solves and sweeps alike.
#pragma once

#include <cstddef>
#include <vector>

#include "sweep.hpp"

namespace rcwa {

// R, T and the power entering the substrate (`into`) of P points and K harmonics, each
// P x K x 2 row-major (column 0: s incidence, 1: p incidence). s waves carry |a|^2 Re(kz),
// p waves (h-normalized) |b|^2 Re(kz / eps) ([Moharam 1995a, Eqs. 16-17] (TE)
// and [Moharam 1995a, Eqs. 35-36] (TM), in the s/p basis of stack.hpp); the incident s
// wave carries Re(kz0) and the p wave Re(kz0 / eps_superstrate), kz0 the incident
// harmonic's superstrate kz. T is zero over an absorbing substrate (nothing reaches
// infinity there); `into` keeps the power that enters it. NaN amplitudes (a polarization
// not solved) give NaN efficiencies.
struct Efficiencies {
    std::size_t points = 0, kept = 0;
    std::vector<double> R, T, into;
};

// From a single solve's StackSolution (its N harmonics; `zero` the incident one).
Efficiencies efficiencies(const StackSolution& solution, int zero, cplx eps_superstrate, cplx eps_substrate);
// From a sweep (its K kept harmonics; `zero` the incident one's column among them).
Efficiencies efficiencies(const SweepResult& sweep, int zero, cplx eps_superstrate, cplx eps_substrate);

}  // namespace rcwa
