"""Total-Lagrangian finite-element model of the skin block pressed by a flat probe.

Nearly incompressible Mooney–Rivlin solid on trilinear hexahedra with the mean-dilatation
(Q1–P0) treatment of the volume term, which avoids volumetric locking: the pressure is one
constant per element, condensed element by element, so the global system holds displacements
only. scikit-fem supplies the mesh, the shape-function gradients and the quadrature; the
hyperelastic residual and tangent are assembled here with vectorised numpy (scikit-fem's
generic form assembly is an order of magnitude slower for this) into a CSR matrix whose
pattern and scatter indices are computed once. Each Newton correction is solved by GMRES with
a factorised tangent as preconditioner, reused across iterations and load steps until GMRES
needs too many iterations (factorising is what costs; see ``SkinModel._newton``). The mesh is
graded toward the singular edges, and predictions Richardson-extrapolate it with a mesh half
as fine (``extrapolated_sweep``).

Quarter model: the block is symmetric about x = 0 and y = 0. Windows are centred on their
face and come in opposite pairs (a module's wall and the one facing it have the same window —
see ``PhysicsParams.modules``), so pure indentation is symmetric about both planes. A lateral
probe displacement along x breaks the symmetry about x = 0 (but keeps y = 0), so that load
path solves the half model x in [-W/2, W/2]; one along y the other half; both, the full
block. The half and full meshes are the quarter mesh mirrored, so on pure indentation all
three give the same numbers to the solver's tolerance (tested). Likewise a tilt of the probe
about x spans y, a tilt about y spans x, a twist about z both, and windows off their face's
centre without a mirror image span the axis they break (``spans_needed``). Tilt and twist
turn the probe's nodes rigidly about the probe's centre (``SkinModel.probe_motion``); the
probe's torque is the moment of their reactions (``SkinModel.probe_torque``).
"""

from .assembly import rotation_matrix, spans_needed
from .extrapolation import extrapolated_sweep, richardson
from .mesh import build_mesh
from .sweep import REPRODUCIBLE_RTOL, Progress, SkinModel, SweepResult

__all__ = ["REPRODUCIBLE_RTOL", "Progress", "SkinModel", "SweepResult", "build_mesh",
           "extrapolated_sweep", "richardson", "rotation_matrix", "spans_needed"]
