"""Finite elements: TET4/TET10 elasticity, Prony viscoelasticity, solvers, transducers (mm N MPa s).

API summary (stable names)::

    from designlab.fem import Model, solve_static
    from designlab.mesh.tetmesh import box_tet_mesh

    mesh = box_tet_mesh(100, 10, 10, 20, 4, 4, material="ABS").quadratic()   # TET10
    model = Model(mesh)                      # materials: mesh.materials {body: name}, or
                                             # Model(mesh, materials={"block": Material(...)})
    model.fix("xmin")                        # facet set / point set / node ids; components="xz"
    model.prescribe("xmax", displacement=(0.1, None, None), case="pull")
    model.traction("xmax", (0, 0, -0.01), case="tip")      # MPa; also pressure(), body_force(),
    model.gravity(case="g")                                # nodal_force()
    hook = model.distributing_coupling("hook", "xmax", ref_point=(110, 5, 5))   # RBE3-like
    model.force(hook, force=(0, 0, -1.0), moment=(0, 0, 0), case="weight")      # N, N mm
    disc = model.rigid("disc", "zmax")                     # RBE2-like 6-dof master (elimination)
    model.fix(disc, "rx")                                  # master dofs "x".."rz"
    model.spring("button", a=(disc, (5, 5, 10)), b=None, k=1e4, axis=(0, 0, -1),
                 preload=0.0, case="default")              # stiff spring = force sensor
    res = solve_static(model, solver="auto")               # all load cases, one factorisation
    res.displacement("tip")            # (n_points, 3) mm
    res.reactions("tip")               # (n_points, 3) N
    res.wrench("xmin", "tip", about=(0, 0, 0))      # (m_x, m_y, m_z, f_x, f_y, f_z)
    res.twist(disc, "tip")             # (w_x, w_y, w_z, v_x, v_y, v_z)
    res.spring_force("button", "tip")  # N, k * elongation along axis + preload
    res.strain(case), res.stress(case), res.von_mises(case)   # (m, nq, 6) Voigt xx yy zz xy xz yz

Viscoelastic histories (Prony series on the material; factor once per step size)::

    from designlab.fem.history import History
    from designlab.fem.viscoelastic import solve_history
    hist = History.step_hold(t_end=60.0, n_steps=120, cases={"weight": 1.0})  # or
    hist = History.piecewise([0, 1, 1, 30], [0, 1, 0, 0], case="weight", dt=0.1)  # ramp, drop
    hh = solve_history(model, hist)    # hh.U (n_dofs, n_steps), hh.t
    hh.wrench("xmin"), hh.twist(disc), hh.spring_force("button"), hh.displacement(step)

Long histories can run on a certified reduced basis (``method="auto"|"reduced"``: the Galerkin
march in basis coordinates, every step's full-order residual checked, the full march as the
fallback; ``hh.march``, ``hh.rom_residual``, ``hh.linear(f)`` for a linear output).

Large deformation (total Lagrangian; dead loads; Newton with increments)::

    from designlab.fem.hyperelastic import NeoHooke, solve_hyperelastic
    hr = solve_hyperelastic(model, {"pulp": NeoHooke.from_linear(0.06, 0.49)},
                            cases={"default": 1.0}, steps=10)   # other bodies St Venant-Kirchhoff

Transducers (``read(result)`` -> one row per load case or time step)::

    from designlab.fem.transducers import StrainGauge, ForceButton, RigidPose, ReactionWrench
    g = StrainGauge(model, "trace", direction=(1, 0, 0))   # or a callable d(x); GF from material
    g.read(res)   # {"strain", "dR_R", "resistance_ohm", "voltage_V"} (2.2 kOhm divider at 5 V)
    ForceButton("button").read(res); RigidPose(disc).read(res); ReactionWrench("xmin").read(res)

Output: ``designlab.fem.output.write_result_vtu(path, res, case)``, ``write_png(path, mesh, u)``.

Building blocks: ``elements`` (TET4, TET10, TRI3, TRI6, quadrature), ``assembly``
(``cell_basis``, ``stiffness``, ``mass``, ``strain_operator``, ``body_load``), ``facets``
(``facet_basis``, ``traction_load``, ``pressure_load``, ``area_weights``), ``solvers``
(``factorize(K, solver="auto"|"direct"|"cholmod"|"amg") -> .solve(F)`` for (n,) or (n, k)),
``materials`` (``Material``, ``MATERIALS``, ``get_material``).
"""

from designlab.fem.materials import MATERIALS, Material, get_material
from designlab.fem.model import Model, RefPoint, Spring, System
from designlab.fem.solvers import factorize
from designlab.fem.static import StaticResult, solve_static
from designlab.fem.history import History, HistoryResult
from designlab.fem.viscoelastic import solve_history

__all__ = ["MATERIALS", "Material", "get_material", "Model", "RefPoint", "Spring", "System",
           "factorize", "StaticResult", "solve_static", "History", "HistoryResult",
           "solve_history"]
