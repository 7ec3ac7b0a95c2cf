"""The :class:`Sensor` record: what ``predict``, ``sweep``, ``optimize`` and the CLI need to know
of one sensor kind, built from its definition (:mod:`designlab.sensors.generic.record`: the
generic virtual test's hooks, or those of the physics it plugs in);
:mod:`designlab.sensors.registry` lists them in ``SENSORS``."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

if TYPE_CHECKING:
    from designlab.loop.model import SensorModel

Progress = Callable[[str], None]


@dataclass(frozen=True)
class Sensor:
    """One sensor kind.

    name:      registry name, also the part's name in :data:`designlab.geometry.parts.PARTS`
    paper:     where its protocol and numbers come from
    protocol:  the protocol dataclass (defaults: the paper's test)
    settings:  the model-settings dataclass (derives from :class:`~designlab.fem.settings.FEMSettings`)
    run:       ``run(part, protocol, settings, progress=...) -> result`` with ``result.report``
    plots:     ``plots(result, report, out_dir) -> [Path]``
    plot_groups: the plots' file names in groups that ``plots(..., only=group)`` draws alone
               (``designlab predict`` has two processes draw them); (): one call draws all
    plots_before_finish: the plots that read only ``run``'s report (not ``finish``'s keys, the
               error bar or a loop model's corrections): their groups are drawn while the
               report is finished
    gains:     ``gains(report, result) -> ({output: {input: gain}}, {output: unit})``: the virtual
               test as a linear model from the loads to the outputs (the loop's base)
    finish:    ``finish(report, result, part, protocol)``: the report's extra keys (load paths,
               the force-error test), in place
    design_protocol: ``(protocol, design, overrides) -> protocol``: defaults that depend on the
               design (the fingertip's load table), applied when no protocol file is given
    apply_model: ``(report, result, model_path, protocol, settings, part=) -> report``: the effects a
               loop learned on a measured sensor added to this design's virtual test (loop ->
               predict); None where not supported
    cached:    ``run`` takes ``cache=`` (a :class:`~designlab.fem.cache.FEMCache`) and computes
               its FEM stage once per distinct model
    meshed:    ``meshed(settings) -> bool``: the prediction rests on a mesh (then it carries a
               discretisation estimate, ``mesh_convergence``); None: always
    convergence: the metrics (dotted paths into the report) whose mesh convergence is reported
    load_cases: ``load_cases(part, protocol, settings, result, cache) -> [LoadCase]``: the
               virtual test's load cases as displacements of ``result.mesh`` (stress and
               safety factor of each); None: the one case of ``result.displacement``
    uncertainty: its Monte Carlo model (:class:`designlab.sensors.distributions.MonteCarloModel`:
               uncertain inputs, metrics, FEM stage, one virtual build); None: no Monte Carlo
    validate:  ``validate(details, out=None, progress=None) -> [Goal]``: the sensor beside its
               paper at the paper's design and protocol (``designlab validate``): one
               :class:`Goal` per compared number; ``details`` (a dict) receives the detailed
               comparison (JSON-able), ``out`` (a folder, or None) its figures; None: none
    row_metrics: report keys a sweep's row carries beside the ones every prediction has
    """

    name: str
    paper: str
    protocol: type
    settings: type
    run: Callable[..., Any]
    plots: Callable[[Any, dict, Path], list[Path]]
    gains: Callable[[dict, Any], tuple[dict, dict]]
    finish: Callable[[dict, Any, Any, Any], None] | None = None
    design_protocol: Callable[[Any, Any, dict | None], Any] | None = None
    apply_model: Callable[..., dict] | None = None
    cached: bool = False
    meshed: Callable[[Any], bool] | None = None
    convergence: tuple[str, ...] = ("condition_number", "hysteresis_percent.overall")
    load_cases: Callable[..., list["LoadCase"]] | None = None
    uncertainty: Any = None
    plot_groups: tuple[tuple[str, ...], ...] = ()
    plots_before_finish: frozenset[str] = frozenset()
    validate: Callable[..., list["Goal"]] | None = None
    row_metrics: tuple[str, ...] = ()

    @property
    def part(self) -> type:
        """The parametric part class (geometry)."""
        from designlab.geometry.parts import PARTS

        return PARTS[self.name]


def settings_from(cls: type, values: dict[str, Any] | None):
    """A sensor's model settings (its ``Sensor.settings`` class) from defaults and ``values``
    (``--setting NAME=VALUE``; lists become tuples); a bad one is a one-line error naming
    ``settings.<name>``."""
    from designlab.errors import ParameterError
    from designlab.params import with_overrides

    values = {k: (tuple(v) if isinstance(v, list) else v) for k, v in (values or {}).items()}
    try:
        return with_overrides(cls, values)
    except ParameterError as exc:
        raise ParameterError(f"settings.{exc.name}", exc.value, exc.allowed) from None


@dataclass(frozen=True)
class Goal:
    """One number of a sensor beside its paper (a row of ``designlab validate``).

    name:   what is compared, its unit in parentheses, e.g. ``"lowest mean G1 hysteresis (%)"``
    value:  the model's number (or True/False for a yes/no goal; None: not computed)
    paper:  the paper's number in the same unit (None: the paper prints none)
    target: the goal in words, e.g. ``"within a factor 2 of 0.98 %"``
    met:    whether the value meets the target (None: no target, shown for reference)
    why:    one sentence: what the number rests on or why it misses
    """

    name: str
    value: float | bool | None
    paper: float | bool | str | None
    target: str
    met: bool | None
    why: str


@dataclass
class LoadCase:
    """One load case of a virtual test on its FEM mesh.

    name:         short name (a VTU field suffix), e.g. ``"h1 @ 0 deg"``
    description:  what is applied where, in words, with the force in N
    displacement: (n_points, 3) mm, long-time
    point, direction, force_N: where the load acts (mm), its unit direction and size (arrows)
    vtu:          written as a point field of ``deformed.vtu`` (all cases are in the JSON)
    """

    name: str
    description: str
    displacement: Any
    point: Any = None
    direction: Any = None
    force_N: float | None = None
    vtu: bool = True


def linear_sensor_model(gains: dict[str, dict[str, float]], units: dict[str, str],
                        provenance: dict) -> "SensorModel":
    """A loop model (``designlab-model`` JSON) whose base is the affine map ``gains``
    (output -> {input: gain}, zero intercept) and which has no effects yet."""
    from designlab.loop.base_models import Base
    from designlab.loop.model import SensorModel

    base = Base("linear", {o: tuple(g) for o, g in gains.items()},
                {o: {"intercept": 0.0, "gains": dict(g)} for o, g in gains.items()})
    return SensorModel(base, {}, units, {}, provenance)
