"""Every right-hand side of pendsweep, each written once as a plain function of floats.

The functions here are plain Python; :func:`compile_physics` compiles the set
for a target (numba's CPU ``njit`` at import, a CUDA device decorator for the
GPU backend) by rebinding the names they call to their compiled versions, so
the same source serves every target. ``PHYSICS`` is the CPU set, and the
module-level names below are replaced by its members when this module is
imported.

Systems and their tuples (SI units):

* :func:`eq11_rhs`, the emulated system, Eq. (11): ``x = (y, y', theta,
  theta')``, ``u = (F_e, sgn held)``, ``p = EQ11 parameters`` (see its
  docstring); :func:`eq11_rhs_trig` is the same with sin and cos of theta
  given, for steps that carry them (:func:`~._rk4.make_rk4_step`).
* :func:`model_rhs`, the numerical model of a substructured test, Eq. (3):
  ``x = (y*, y*')``, ``u = F_e - F_fb``, ``p = (M1, C1, K, k3)``.
* :func:`servo_rig_rhs`, the rig with the servo actuator: platform ``x'' =
  ws^2 (u - x) - 2 zeta ws x'`` carrying the pendulum, ``x = (x, x', theta,
  theta')``, ``u`` the delayed command, ``p = (ws^2, 2 zeta ws, sgn, m, l, b1, b2, b3, g)``.
  Its servo law :func:`servo_acc` is shared with the diagnosis's transfer models
  (:func:`pendsweep.kernels._measured.transfer_trace`).
* :func:`pivot_pendulum_rhs`, the pendulum on a pivot of prescribed
  acceleration (Eq. (2); a fixed pivot for free swing): ``x = (theta,
  theta')``, ``u = x''``, ``p = (sgn, m, l, b1, b2, b3, g)``.
* :func:`mathieu_rhs`, the damped Hill equation of the Floquet analysis:
  ``x = (theta, theta')``, ``u`` the time-varying stiffness, ``p = (kappa_p,)``.

The pendulum damping law :func:`pendulum_damping` is shared by all pendulum
equations.
"""

import math
import types

import numba as nb

from ._sincos import sincos_poly


def signum(x):
    """-1, 0 or 1 as a float (0 for NaN).

    Written as arithmetic on the two comparisons rather than as branches: in
    the batched lane loop the branches became boolean masks that AVX2 (which
    has no mask registers) repacked at every stage.
    """
    return (1.0 if x > 0.0 else 0.0) - (1.0 if x < 0.0 else 0.0)


def pendulum_damping(thd, sgn, b1, b2, b3):
    """Pendulum damping torque ``f_d = b1 sgn + b2 w + b3 w^2 sgn`` [N m] at rate ``thd``, sign ``sgn``."""
    return b1 * sgn + b2 * thd + b3 * thd * thd * sgn


def pendulum_acc(th, thd, xdd, sgn, m, l, b1, b2, b3, g):
    """Eq. (2) solved for theta'': ``-(f_d + m l (g + x'') sin theta) / (m l^2)`` [rad/s^2]."""
    fd = pendulum_damping(thd, sgn, b1, b2, b3)
    return -(fd + m * l * (g + xdd) * math.sin(th)) / (m * l * l)


def sin_cos(th, vector):
    """``(sin th, cos th)``: libm, or the vectorisable :func:`sincos_poly` when ``vector``."""
    if vector:
        return sincos_poly(th)
    return math.sin(th), math.cos(th)


def eq11_rhs(x, u, p):
    """Eq. (11): the complete pendulum-oscillator system.

    Parameters
    ----------
    x : (y [m], y' [m/s], theta [rad], theta' [rad/s])
    u : (F_e [N], sgn)
        External force at the stage time and the signum of theta' held over
        the step (used unless ``per_stage``).
    p : (m, l, b1, b2, b3, g, M, C, K, k3, per_stage, vector, inv_l, inv_m)
        Physical parameters in the kernel order; ``per_stage`` evaluates the
        signum at every stage; ``vector`` (a compile-time constant at every
        call site) takes sin/cos from :func:`sincos_poly` and replaces the
        divisions by ``l`` and ``m`` with multiplications by ``inv_l = 1/l``
        and ``inv_m = 1/m`` and the two by the denominator with one
        reciprocal: divisions dominate the cost of the vectorised kernel.
    """
    vector = p[11]  # the ``vector`` flag of the parameter tuple
    return eq11_rhs_trig(x, sin_cos(x[2], vector), u, p)


def eq11_rhs_trig(x, trig, u, p):
    """:func:`eq11_rhs` given ``trig = (sin theta, cos theta)`` of the state (theta itself is not used)."""
    y, yd, _, thd = x
    force, held = u
    m, l, b1, b2, b3, g, M, C, K, k3, per_stage, vector, inv_l, inv_m = p
    sgn = signum(thd) if per_stage else held
    s, c = trig
    fd = pendulum_damping(thd, sgn, b1, b2, b3)
    denom = M + m * c * c
    if vector:
        inv_den = 1.0 / denom
        common = force - C * yd - K * y - k3 * y * y * y - m * l * thd * thd * c + s * fd * inv_l
        ydd = (common + m * g * s * s) * inv_den
        thdd = -(s * inv_l) * (common + (M + m) * g) * inv_den - fd * (inv_l * inv_l * inv_m)
        return yd, ydd, thd, thdd
    common = force - C * yd - K * y - k3 * y * y * y - m * l * thd * thd * c + s * fd / l
    ydd = (common + m * g * s * s) / denom
    thdd = -(s / l) * (common + (M + m) * g) / denom - fd / (m * l * l)
    return yd, ydd, thd, thdd


def model_rhs(x, u, p):
    """Eq. (3): ``M1 y*'' + C1 y*' + K y* + k3 y*^3 = u`` with ``u = F_e - F_fb`` [N]."""
    y, v = x
    M1, C1, K, k3 = p
    return v, (u - C1 * v - K * y - k3 * y * y * y) / M1


def servo_acc(xp, xd, u, ws2, tzw):
    """Second-order servo: platform acceleration ``ws^2 (u - x) - 2 zeta ws x'`` [m/s^2] for command ``u``."""
    return ws2 * (u - xp) - tzw * xd


def servo_rig_rhs(x, u, p):
    """The rig with the servo actuator: platform position ``x`` follows command ``u`` [m]."""
    xp, xd, th, thd = x
    ws2, tzw, sgn, m, l, b1, b2, b3, g = p
    a = servo_acc(xp, xd, u, ws2, tzw)
    return xd, a, thd, pendulum_acc(th, thd, a, sgn, m, l, b1, b2, b3, g)


def pivot_pendulum_rhs(x, u, p):
    """The pendulum on a pivot with acceleration ``u`` [m/s^2] (0: a fixed pivot)."""
    th, thd = x
    sgn, m, l, b1, b2, b3, g = p
    return thd, pendulum_acc(th, thd, u, sgn, m, l, b1, b2, b3, g)


def mathieu_rhs(x, u, p):
    """Damped Hill equation ``theta'' + kappa_p theta' + u(t) theta = 0`` with stiffness ``u`` [1/s^2]."""
    th, v = x
    (kappa_p,) = p
    return v, -kappa_p * v - u * th


#: Names compiled by :func:`compile_physics`, callees before callers.
PHYSICS_FUNCTIONS = (
    "signum",
    "pendulum_damping",
    "pendulum_acc",
    "sin_cos",
    "eq11_rhs_trig",
    "eq11_rhs",
    "model_rhs",
    "servo_acc",
    "servo_rig_rhs",
    "pivot_pendulum_rhs",
    "mathieu_rhs",
)
_PLAIN = {name: globals()[name] for name in PHYSICS_FUNCTIONS}


def compile_physics(jit, overrides=None):
    """Compile every right-hand side for one target.

    Each plain function is re-created with a globals mapping in which the
    names it calls refer to their compiled versions, then compiled with
    ``jit``. ``overrides`` replaces helpers for targets that cannot compile
    them (e.g. ``{"sincos_poly": ...}`` on a GPU, which has its own sin/cos).

    Returns
    -------
    types.SimpleNamespace
        The compiled functions under their names.
    """
    namespace = dict(globals())
    namespace.update(overrides or {})
    compiled = {}
    for name in PHYSICS_FUNCTIONS:
        plain = _PLAIN[name]
        fn = types.FunctionType(plain.__code__, namespace, name, plain.__defaults__, plain.__closure__)
        fn.__qualname__ = plain.__qualname__
        fn.__doc__ = plain.__doc__
        compiled[name] = jit(fn)
        namespace[name] = compiled[name]
    return types.SimpleNamespace(**compiled)


#: The CPU set (numba, inlined at every call site, cached on disk).
PHYSICS = compile_physics(nb.njit(cache=True, nogil=True, inline="always"))
globals().update(vars(PHYSICS))
