"""RCWA core (C++17, LAPACK from scipy-openblas32). See rcwa/cpp/*.hpp."""

from collections.abc import Sequence
import enum
from typing import Annotated

import numpy
from numpy.typing import NDArray


class LayerKind(enum.Enum):
    """How a layer's modes are found, and so which matrices it carries."""

    UNIFORM = 0
    """Homogeneous: modes in closed form, no matrices."""

    LAMELLAR = 1
    """
    1D grating (harmonics along x): matrices E, Exx; two N x N eigen-solves.
    """

    GENERAL = 2
    """
    2D or anisotropic: matrices E, Exx, Exy, Eyx, Eyy; one 2N x 2N eigen-solve.
    """

class StackMethod(enum.Enum):
    """How the layers are combined (stack.hpp)."""

    ENHANCED_TRANSMITTANCE = 1
    """Moharam, Pommet, Grann & Gaylord 1995: one bottom-up sweep."""

    SCATTERING_MATRIX = 0
    """Redheffer star product of layer scattering matrices (Rumpf 2011)."""

class Incidence(enum.Enum):
    """Which incident polarizations a single solve must answer."""

    S = 0
    """s (TE) incidence only, where the stack decouples; else both."""

    P = 1
    """p (TM) incidence only, where the stack decouples; else both."""

    BOTH = 2
    """Both polarizations."""

class LayerInput:
    """
    One layer as the core receives it: its kind, its thickness times k0, the permittivity of a uniform layer, and the N x N Fourier matrices of a patterned one (lamellar: E, Exx, or E, [[1/eps]] with inverse_rule; general: E, Exx, Exy, Eyx, Eyy). Checked on construction (ValueError naming the field).
    """

    def __init__(self, kind: LayerKind, k0_thickness: float, permittivity: complex = ..., matrices: Sequence[Annotated[NDArray[numpy.complex128], dict(shape=(None, None), device='cpu', writable=False)]] = [], inverse_rule: bool = False) -> None: ...

    @property
    def kind(self) -> LayerKind: ...

    @property
    def inverse_rule(self) -> bool:
        """
        A lamellar layer given as E and [[1/eps]] (Li's inverse rule): Exx = [[1/eps]]^-1 is formed in the core where a TM family needs it.
        """

    @property
    def k0_thickness(self) -> float:
        """Thickness times k0 (radians of vacuum phase)."""

    @property
    def permittivity(self) -> complex:
        """Relative permittivity of a uniform layer."""

    @property
    def size(self) -> int:
        """N: the matrices are N x N (0 for a uniform layer)."""

    @property
    def matrices(self) -> list[Annotated[NDArray[numpy.complex128], dict(shape=(None, None))]]:
        """Copies of the Fourier matrices, in the order given."""

    @staticmethod
    def lamellar(k0_thickness: float, period: float, segments: Sequence[tuple[float, float, complex]], harmonics: int, inverse_rule: bool = True) -> LayerInput:
        """
        A lamellar layer from its permittivity profile on [0, period), as (x0, x1, eps) segments: E = [[eps]] and [[1/eps]] (inverse_rule, Li 1996) or Exx = E (Laurent), for `harmonics` orders m = -M..M (profile.hpp).
        """

    def __repr__(self) -> str: ...

class StackSolution:
    """
    Outgoing amplitudes of one solve for unit s incidence (column 0) and unit p incidence (column 1). Row i is the s amplitude of harmonic i (E along s-hat), row N + i its p amplitude (h = Z0 H along s-hat).
    """

    @property
    def reflected(self) -> Annotated[NDArray[numpy.complex128], dict(shape=(None, None), writable=False)]:
        """Reflected amplitudes into the superstrate, (2N, 2)."""

    @property
    def transmitted(self) -> Annotated[NDArray[numpy.complex128], dict(shape=(None, None), writable=False)]:
        """Transmitted amplitudes into the substrate, (2N, 2)."""

    @property
    def kz_superstrate(self) -> Annotated[NDArray[numpy.complex128], dict(shape=(None,), writable=False)]:
        """kz / k0 of each harmonic in the superstrate, outgoing branch, (N,)."""

    @property
    def kz_substrate(self) -> Annotated[NDArray[numpy.complex128], dict(shape=(None,), writable=False)]:
        """kz / k0 of each harmonic in the substrate, outgoing branch, (N,)."""

    def efficiencies(self, zero_order: int, eps_superstrate: complex, eps_substrate: complex) -> tuple[NDArray[numpy.float64], NDArray[numpy.float64], NDArray[numpy.float64]]:
        """
        (R, T, into): each (N, 2), columns s and p incidence: the efficiencies of the harmonics and the power entering the substrate (T is zero over an absorbing one) per unit incident power (efficiency.hpp).
        """

    @property
    def decoupled(self) -> bool:
        """
        Whether TE and TM were solved apart on N x N blocks (1D, every ky = 0: polarized.hpp); a polarization not asked for then has NaN amplitudes.
        """

    @property
    def direct(self) -> bool:
        """
        Whether a one-layer stack was solved as one boundary system instead of through W^-1 and V^-1: 4N x 4N (stack.cpp, solve_direct), or 2N x 2N per polarization in classical mount (polarized.cpp, solve_polarized_direct).
        """

    @property
    def hermitian_solves(self) -> int:
        """
        Eigen-solves of lossless 1D layers done by Hermitian solvers (zheevd, zhegvd) instead of zgeev.
        """

    @property
    def real_solves(self) -> int:
        """
        Of hermitian_solves, those done in real arithmetic (dsyevd, dsygvd): the layer is symmetric about a point, and moving the origin there makes its matrices real (linalg.hpp, real_by_phase).
        """

    @property
    def inverse_iteration_solves(self) -> int:
        """
        Eigen-solves of lossy 1D layers (fewer than 75 harmonics) done by the QR algorithm for the eigenvalues and inverse iteration for the eigenvectors (linalg.hpp, eig_small) instead of zgeev.
        """

    @property
    def complex_symmetric_solves(self) -> int:
        """
        Eigen-solves of lossy 1D layers symmetric about a point done as complex symmetric problems: tridiagonal form by complex-orthogonal reflectors, QL, inverse iteration, one refinement step, accepted on a residual check (complex_symmetric.hpp) instead of eig_small or zgeev.
        """

    @property
    def sectors_solved(self) -> int:
        """
        Mirror-symmetry sectors solved (sectors.hpp), of sectors_total; 0 of 0 where none were used. A polarization not asked for then has NaN amplitudes.
        """

    @property
    def sectors_total(self) -> int:
        """
        The number of mirror-symmetry sectors the point splits into (2 or 4), 0 where none were used.
        """

class SweepSolution:
    """
    Amplitudes of the K kept harmonics at P incident directions, as StackSolution per point restricted to the kept rows (s rows, then p rows), and the work done.
    """

    @property
    def reflected(self) -> Annotated[NDArray[numpy.complex128], dict(shape=(None, None, None), writable=False)]:
        """Reflected amplitudes, (P, 2K, 2)."""

    @property
    def transmitted(self) -> Annotated[NDArray[numpy.complex128], dict(shape=(None, None, None), writable=False)]:
        """Transmitted amplitudes, (P, 2K, 2)."""

    @property
    def kz_superstrate(self) -> Annotated[NDArray[numpy.complex128], dict(shape=(None, None), writable=False)]:
        """kz / k0 of the kept harmonics in the superstrate, (P, K)."""

    @property
    def kz_substrate(self) -> Annotated[NDArray[numpy.complex128], dict(shape=(None, None), writable=False)]:
        """kz / k0 of the kept harmonics in the substrate, (P, K)."""

    def efficiencies(self, zero_column: int, eps_superstrate: complex, eps_substrate: complex) -> tuple[NDArray[numpy.float64], NDArray[numpy.float64], NDArray[numpy.float64]]:
        """
        (R, T, into): each (P, K, 2), as StackSolution.efficiencies per point; zero_column: the incident harmonic's column among the kept ones.
        """

    @property
    def sector_points(self) -> int:
        """
        Points solved in mirror-symmetry sectors (sectors.hpp): those at kx0 = 0 or ky0 = 0 of a mirror.
        """

    @property
    def eigen_solves(self) -> int:
        """
        Lamellar eigen-solves (two per 1D layer and group of points sharing kx0).
        """

    @property
    def eigen_refined(self) -> int:
        """
        Of the eigen-solves, those refined from a neighbouring kx0's eigenvectors.
        """

class EigenDecomposition:
    """A V = V diag(values), right eigenvectors as columns."""

    @property
    def values(self) -> Annotated[NDArray[numpy.complex128], dict(shape=(None,), writable=False)]:
        """Eigenvalues, (N,)."""

    @property
    def vectors(self) -> Annotated[NDArray[numpy.complex128], dict(shape=(None, None), writable=False)]:
        """Eigenvectors as columns, (N, N), each of unit norm."""

def solve_stack(kx: Annotated[NDArray[numpy.float64], dict(shape=(None,), device='cpu', writable=False)], ky: Annotated[NDArray[numpy.float64], dict(shape=(None,), device='cpu', writable=False)], zero_order: int, eps_superstrate: complex, eps_substrate: complex, s_direction: tuple[float, float], layers: Sequence[LayerInput], method: StackMethod = StackMethod.ENHANCED_TRANSMITTANCE, incidence: Incidence = Incidence.BOTH, fast_paths: bool = True, mirrors: Sequence[tuple[int, Sequence[int], Sequence[complex]]] = []) -> StackSolution:
    """
    One solve. kx, ky: (N,) tangential wave vectors / k0 of the harmonics; zero_order: the index of the incident wave's; s_direction: s-hat where kx = ky = 0; layers from the superstrate down. incidence: the polarizations needed; fast_paths=False forces the general 2N x 2N path (for checking the fast ones). mirrors: the cell's mirrors as (axis, partner, phase) (sweep.hpp, Mirror), used where the point respects them (sectors.hpp).
    """

def sweep(dkx: Annotated[NDArray[numpy.float64], dict(shape=(None,), device='cpu', writable=False)], dky: Annotated[NDArray[numpy.float64], dict(shape=(None,), device='cpu', writable=False)], zero_order: int, eps_superstrate: complex, eps_substrate: complex, layers: Sequence[LayerInput], kx0: Annotated[NDArray[numpy.float64], dict(shape=(None,), device='cpu', writable=False)], ky0: Annotated[NDArray[numpy.float64], dict(shape=(None,), device='cpu', writable=False)], s_x: Annotated[NDArray[numpy.float64], dict(shape=(None,), device='cpu', writable=False)], s_y: Annotated[NDArray[numpy.float64], dict(shape=(None,), device='cpu', writable=False)], keep: Sequence[int], method: StackMethod = StackMethod.ENHANCED_TRANSMITTANCE, threads: int = 1, mirrors: Sequence[tuple[int, Sequence[int], Sequence[complex]]] = []) -> SweepSolution:
    """
    Many incident directions (P points) at one wavelength: harmonic i of point p has kx0[p] + dkx[i], ky0[p] + dky[i]; the harmonics listed in keep are returned. Points sharing kx0 share 1D eigen-solves; points respecting one of the mirrors (as in solve_stack) are solved in mirror-symmetry sectors.
    """

def eig_from_guess(A: Annotated[NDArray[numpy.complex128], dict(shape=(None, None), device='cpu', writable=False)], guess: Annotated[NDArray[numpy.complex128], dict(shape=(None, None), device='cpu', writable=False)]) -> EigenDecomposition | None:
    """
    Eigen-decomposition of A refined from approximate eigenvectors, or None where it declines.
    """

def eig_complex_symmetric(A: Annotated[NDArray[numpy.complex128], dict(shape=(None, None), device='cpu', writable=False)]) -> EigenDecomposition | None:
    """
    Eigen-decomposition of a complex symmetric A (complex_symmetric.hpp), or None where it breaks down or fails its residual check.
    """

def eig_small(A: Annotated[NDArray[numpy.complex128], dict(shape=(None, None), device='cpu', writable=False)]) -> EigenDecomposition | None:
    """
    Eigen-decomposition by zhseqr and inverse iteration (linalg.hpp, eig_small), or None where it declines.
    """

def set_blas_threads(n: int) -> None:
    """Number of OpenBLAS threads (1 when the core runs its own threads)."""
