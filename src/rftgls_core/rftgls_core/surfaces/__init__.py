"""Granular limit surfaces: fit a representation to W_ext(t), query capacity and slip twist.

    problem = GLSProblem(wrench_fn, Scaling(force_N, length_m))   # or choose_scaling(...)
    surf = TwistMeshSurface(n_twists=2000).fit(problem)
    r = surf.capacity(phi)          # CapacityResult: status, capacity_N, slip_twist, ...

Representations: TwistMeshSurface (primary), DirectSurface (root-finding reference),
EllipsoidSurface (LG04, paper option a), AlphaShapeSurface (MATLAB alphaShape, paper option b).
"""
from .alpha_shape import AlphaComplex, AlphaShapeSurface, alpha_shape
from .base import CapacityResult, GLSProblem, LimitSurface
from .direct import DirectSurface
from .ellipsoid import EllipsoidSurface, fit_ellipsoid
from .registry import METHOD_NAMES, surface_class
from .sampling import fibonacci_sphere
from .scaling import Scaling, choose_scaling
from .twist_mesh import TwistMeshSurface
from .twist_sphere import TwistSphere

__all__ = ['AlphaComplex', 'AlphaShapeSurface', 'CapacityResult', 'DirectSurface',
           'EllipsoidSurface', 'GLSProblem', 'LimitSurface', 'METHOD_NAMES', 'Scaling',
           'TwistMeshSurface', 'TwistSphere', 'alpha_shape', 'choose_scaling',
           'fibonacci_sphere', 'fit_ellipsoid', 'surface_class']
