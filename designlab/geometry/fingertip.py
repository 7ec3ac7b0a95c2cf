"""Seed 001: the 3D-printed cantilever fingertip on a steel ball and three FSS force sensors.

Frame (mm): origin at the centre of the 9.4 mm steel ball, z up the fingertip axis. The printed
fingertip's flat bottom is the plane ``z = 0``; it holds the upper half of the ball in a spherical
seat and is detachable. Its outline (Fig. 1 of the paper: "height h and radius r") is a cylinder
of radius ``fingertip_radius`` (9, total diameter 18 mm) that rises ``h`` mm, then rounds over
with an edge radius ``r``: ``r = fingertip_radius`` gives the hemispherical dome of the optimised
sensor (h = 0, r = 9, total height 20 mm, Table III), ``r = 0`` a flat top. Its top is at
``z = h + r``. Below a ``gap`` (so forces reach the sensors only through the ball) the printed base
holds three Honeywell FSS015 sensors in wells whose axes point at the ball centre 45 deg from
the vertical, at azimuths 270/30/150 deg (eqs. 4-6 of the paper: sensors r, g, b). The bottom
cap carries an M2.5 cantilever bolt that runs up through the base and is screwed into a tapped
blind hole in the ball, pulling it onto the sensors (preload). The tested sensor of Table II
(total height 48.5 mm) is :meth:`CantileverFingertip.table_ii`.

Load points follow the hanging-weight tests: ``h1..`` are lateral loads on the fingertip's side at
heights ``z = h_i`` above the fingertip bottom (Table III heights, or Table II with
``load_table="II"``), ``r1..`` axial loads (-z) on the top at radii ``r_i``. With the default
dome the Table III heights and radii are a mirrored set of points on the dome, which is how we
read the paper's datum: heights are measured from the dome's base plane (the ball centre).

Bodies: ``fingertip``, ``base``, ``cap`` (ABS, printed, meshed); ``ball`` and ``bolt`` (steel) and
``sensor_1..3`` (FSS015 body + steel button, approximate 5 x 5 x 2.3 mm outline): bought, coupled
in FEM rather than meshed; with ``skin_thickness > 0`` a cast silicone ``skin`` over the fingertip
(the paper's optional coating; meshed), whose outer surface then carries the load points.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from build123d import (Axis, Box, CenterArc, Cylinder, Line, Plane, Pos, Sphere, Wire, Face,
                       revolve)

from designlab.geometry.body import Body, FacetSelector
from designlab.geometry.solids import single_solid
from designlab.params import at_least, at_most, rng, validate, within

#: seed 001 Table II: heights of the lateral (G1) loads and radii of the axial (G2) loads, mm
TABLE_II_HEIGHTS = (22.76, 21.92, 20.52, 18.72, 16.76, 14.76, 12.76, 10.76, 8.76)
TABLE_II_RADII = (0.0, 1.90, 3.69, 5.12, 6.03)
#: seed 001 Table III (optimised sensor)
TABLE_III_HEIGHTS = (8.41, 7.71, 6.62, 5.19, 3.51, 1.65)
TABLE_III_RADII = (1.65, 3.51, 5.19, 6.62, 7.71, 8.41)
#: sensor azimuths (deg) of eqs. 4-6 (sensors r, g, b) and their elevation from the horizontal
SENSOR_AZIMUTHS_DEG = (270.0, 30.0, 150.0)
SENSOR_ELEVATION_DEG = 45.0
#: how far the ball cavity's floor lies below the ball's 0.5 mm clearance, mm
CAVITY_FLOOR_DROP = 1.1
#: minimum printed wall (mm)
MIN_WALL = 1.0
#: the ball cavity's radial clearance around the ball (mm)
CAVITY_CLEARANCE = 0.5
#: a sensor well starts this far inside the ball's radius, along its axis (mm)
WELL_FRONT_INSET = 0.7
#: least skin (mm, two 0.1 mm layers) between the base's top face and a sensor well's highest
#: corner in the base (:func:`well_top_skin`): the 5 mm wells of a 6 mm ball cut through the
#: top face (the printability check then failed on the wedges they leave)
WELL_TOP_SKIN = 0.2
#: wire channel radius (mm) and its leg along the sensor axis below each well floor (mm): the
#: horizontal leg's top stays a wall's width under the slanted floor
WIRE_RADIUS = 0.6
WIRE_DROP = 1.0
#: outline features smaller than this are snapped away when building (mm)
EPS = 1e-3


@dataclass(frozen=True)
class CantileverFingertip:
    """Parameters of the cantilever fingertip sensor (mm). Defaults: the optimised sensor of
    seed 001 Table III (h = 0, r = 9, diameter 18, total height 20)."""

    h: float = field(default=0.0, metadata=rng(0, 40, unit="mm",
                                               doc="straight height of the fingertip"))
    r: float = field(default=9.0, metadata=rng(0, 9, unit="mm",
                                               doc="top rounding radius (<= fingertip_radius)"))
    fingertip_radius: float = field(default=9.0, metadata=rng(5.5, 15, unit="mm",
                                                              doc="seed 001: diameter 18"))
    ball_diameter: float = field(default=9.4, metadata=rng(
        6, 12, unit="mm", doc="seed 001: 9.4; takes the bolt; at least 9.182 with the 5 mm "
                              "sensors and the 0.5 mm gap (the wells stay under the base's top)"))
    gap: float = field(default=0.5, metadata=rng(0.2, 3, unit="mm",
                                                 doc="fingertip-to-base clearance"))
    base_height: float = field(default=8.0, metadata=rng(
        4, 30, unit="mm", doc="height of the printed base holding the three sensor wells"))
    base_radius: float = field(default=9.0, metadata=rng(
        6, 20, unit="mm", doc="radius of the printed base (sensor wells plus a wall)"))
    cap_thickness: float = field(default=2.5, metadata=rng(
        1.5, 8, unit="mm", doc="bottom cap under the base; carries the cantilever bolt head"))
    sensor_size: float = field(default=5.0, metadata=rng(2, 10, unit="mm",
                                                         doc="FSS015 body, approx."))
    sensor_thickness: float = field(default=2.3, metadata=rng(
        1, 6, unit="mm", doc="FSS015 body thickness behind its button, approx."))
    button_radius: float = field(default=0.8, metadata=rng(
        0.3, 2, unit="mm", doc="radius of the FSS015 steel ball button that the ball presses"))
    well_clearance: float = field(default=0.1, metadata=rng(
        0.02, 0.5, unit="mm", doc="play around each sensor in its well"))
    bolt_diameter: float = field(default=2.5, metadata=rng(1.6, 4, unit="mm", doc="M2.5"))
    bolt_length: float = field(default=10.0, metadata=rng(3, 40, unit="mm",
                                                          doc="under-head length (M2.5x10)"))
    head_diameter: float = field(default=4.5, metadata=rng(
        2, 8, unit="mm", doc="diameter of the cantilever bolt's head under the cap"))
    head_height: float = field(default=1.75, metadata=rng(
        0.8, 4, unit="mm", doc="height of the cantilever bolt's head under the cap"))
    load_table: str = field(default="III", metadata=rng(choices=("II", "III"),
                                                        doc="seed 001 table of load points"))
    load_patch_radius: float = field(default=1.0, metadata=rng(
        0.2, 3, unit="mm", doc="radius of the surface patch that carries each load point's force"))
    skin_thickness: float = field(default=0.0, metadata=rng(0, 3, unit="mm",
                                                            doc="silicone coating, 0 = none"))

    def __post_init__(self):
        validate(self)
        self._check()

    @classmethod
    def table_ii(cls) -> "CantileverFingertip":
        """The sensor of seed 001 Table II (total height 48.5 mm, diameter 18 mm) read from its
        own table, heights measured from the ball centre as every arm here (and Table III's
        dome): its load points h1..h4 / r2..r5 lie on a 6.37 mm dome centred 16.70 mm up (the
        fingertip h 16.70, r = fingertip_radius = 6.37, top 23.07 mm up), so the 48.5 mm leave
        25.43 mm under the ball (gap 0.5 + base 22.43 + cap 2.5), spanned by a 24.43 mm M2.5
        bolt, the paper's "extended cantilever-bolt" (Sec. II-B). The paper draws no base:
        ``examples/fingertip_table_ii.toml``, docs/validation/fingertip.md."""
        return cls(h=16.70, r=6.37, fingertip_radius=6.37, base_height=22.43, bolt_length=24.43,
                   load_table="II")

    @classmethod
    def tested(cls) -> "CantileverFingertip":
        """Table II's load points on a tall fingertip (h 28.5, r 9: 48.5 mm total) on the
        optimised sensor's base: the heights on its straight side, its top not the table's
        dome. The model's Table II sensor before :meth:`table_ii`, kept for the examples and
        tests that compare with it."""
        return cls(h=28.5, r=9.0, load_table="II")

    # ------------------------------------------------------------------ derived geometry (mm)
    @property
    def ball_radius(self) -> float:
        return self.ball_diameter / 2

    @property
    def top_z(self) -> float:
        """Top of the outer surface (the skin's, if any)."""
        return self.h + self.r + self.skin_thickness

    @property
    def outer_radius(self) -> float:
        """Radius of the outer surface (printed fingertip plus skin)."""
        return self.fingertip_radius + self.skin_thickness

    @property
    def base_z(self) -> tuple[float, float]:
        """Bottom and top of the base."""
        return -self.gap - self.base_height, -self.gap

    @property
    def cap_z(self) -> tuple[float, float]:
        lo = self.base_z[0]
        return lo - self.cap_thickness, lo

    @property
    def total_height(self) -> float:
        return self.top_z - self.cap_z[0]

    @property
    def well_depth(self) -> float:
        """Distance from the ball centre to a well floor along the sensor axis."""
        return self.ball_radius + self.button_radius + self.sensor_thickness

    @property
    def bolt_top_z(self) -> float:
        """Upper end of the bolt (inside the ball's tapped hole); its head bears on the cap's
        bottom face and stands below it (the robot mount has a recess for it)."""
        return self.cap_z[0] + self.bolt_length

    def sensor_axes(self) -> tuple[np.ndarray, np.ndarray]:
        """``(axes, contacts)``: (3, 3) unit vectors along which the sensors push the ball
        (eqs. 4-6: azimuths 270/30/150 deg, 45 deg from the vertical) and the (3, 3) contact
        points on the ball (``-ball_radius * axis``)."""
        el = math.radians(SENSOR_ELEVATION_DEG)
        az = np.radians(SENSOR_AZIMUTHS_DEG)
        axes = np.stack([math.cos(el) * np.cos(az), math.cos(el) * np.sin(az),
                         np.full(3, math.sin(el))], axis=1)
        return axes, -self.ball_radius * axes

    def surface_radius(self, z: float) -> float:
        """Radius of the outer surface at height ``z`` (0 <= z <= top_z); with a skin, the
        outline is offset by its thickness (edge radius ``r + skin_thickness``)."""
        R, r = self.outer_radius, self.r + self.skin_thickness
        if z <= self.h:
            return R
        return (R - r) + math.sqrt(max(r ** 2 - (z - self.h) ** 2, 0.0))

    def surface_height(self, rho: float) -> float:
        """Height of the outer top surface at radius ``rho`` (0 <= rho <= outer_radius)."""
        R, r = self.outer_radius, self.r + self.skin_thickness
        if rho <= R - r:
            return self.top_z
        return self.h + math.sqrt(max(r ** 2 - (rho - (R - r)) ** 2, 0.0))

    def load_table_values(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """(heights, radii) of the selected seed 001 table (mm)."""
        if self.load_table == "II":
            return TABLE_II_HEIGHTS, TABLE_II_RADII
        return TABLE_III_HEIGHTS, TABLE_III_RADII

    def load_points(self, azimuth_deg: float = 0.0) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """``{"h1": (point, direction), ..., "r1": ...}``: lateral loads at the table heights on
        the side (direction horizontal, towards the axis, from ``azimuth_deg``) and axial loads
        (direction -z) at the table radii on the top. Points on the surface, mm. Table points that
        miss a smaller fingertip (height above its top or radius beyond its edge) are left out."""
        heights, radii = self.load_table_values()
        a = math.radians(azimuth_deg)
        e = np.array([math.cos(a), math.sin(a), 0.0])
        out = {}
        for i, z in enumerate(heights, 1):
            if z < self.top_z:
                out[f"h{i}"] = (np.array([*(self.surface_radius(z) * e[:2]), z]), -e.copy())
        for i, rho in enumerate(radii, 1):
            if rho > self.outer_radius:
                continue
            out[f"r{i}"] = (np.array([*(rho * e[:2]), self.surface_height(rho)]),
                            np.array([0.0, 0.0, -1.0]))
        return out

    def load_locations(self, azimuth_deg: float = 0.0) -> dict:
        """The load points as build123d ``Location``s whose z axis is the load direction."""
        from build123d import Location

        return {k: Location(Plane(origin=tuple(p), z_dir=tuple(d)))
                for k, (p, d) in self.load_points(azimuth_deg).items()}

    def _check(self) -> None:
        """Constraints between parameters; each error names a parameter whose allowed range
        (printed as an allowed value) is not empty given the others."""
        R, rb = self.fingertip_radius, self.ball_radius
        if 0 < self.skin_thickness < 0.2:  # thinner is no castable coating (and no solid)
            at_least("skin_thickness", self.skin_thickness, 0.2, "a cast coating; 0 = none")
        at_least("fingertip_radius", R, rb + MIN_WALL, f"ball radius {rb:g} + {MIN_WALL:g} mm wall")
        at_most("r", self.r, R, f"fingertip_radius = {R:g} mm")
        # r's range [ball radius + wall - h, fingertip_radius] is not empty: R >= ball radius + wall
        at_least("r", self.r, rb + MIN_WALL - self.h, f"with h={self.h:g}: h + r >= ball radius + "
                 f"{MIN_WALL:g} mm wall covers the seat")
        # base: the well floors must stay inside the base (wall MIN_WALL)
        s2 = (self.sensor_size + 2 * self.well_clearance) / 2
        c = math.cos(math.radians(SENSOR_ELEVATION_DEG))
        z_low = -(self.well_depth * c + s2 * c)
        at_least("base_height", self.base_height, -z_low + MIN_WALL - self.gap,
                 f"sensor wells + {MIN_WALL:g} mm floor")
        rho = math.hypot(self.well_depth * c + s2 * c, s2)
        at_least("base_radius", self.base_radius, rho + MIN_WALL, "sensor wells + wall")
        self._check_well_top(s2)
        at_least("head_diameter", self.head_diameter, self.bolt_diameter + 0.8,
                 "bolt_diameter + 0.8")
        # the ball takes the bolt (radius >= bolt diameter + 0.4): not empty, as ball_diameter >= 6
        at_most("bolt_diameter", self.bolt_diameter, rb - 0.4, "ball radius - 0.4")
        lo, hi = -rb + 2.0, -0.5  # thread engagement >= 2 mm, blind hole below the ball centre
        base = self.bolt_length - self.bolt_top_z  # cap bottom to ball centre
        within("bolt_length", self.bolt_length, base + lo, base + hi,
               ">= 2 mm thread in the ball, blind hole below its centre")

    def _check_well_top(self, s2: float) -> None:
        """Each sensor well (half width ``s2``) leaves the ball cavity at least
        :data:`WELL_TOP_SKIN` under the base's top face. The error names the ball diameter
        (its least value given the sensors and the gap), or when that exceeds its range the
        sensor size, then the gap (their largest values given the others)."""
        if well_top_skin(self.ball_radius, s2, self.gap) >= WELL_TOP_SKIN - 1e-9:
            return
        why = f"the sensor wells stay {WELL_TOP_SKIN:g} mm under the base's top face"
        d_max = self.__dataclass_fields__["ball_diameter"].metadata["hi"]
        lo = 2 * _bisect(lambda rb: well_top_skin(rb, s2, self.gap), 0.0, 100.0) + 1e-4
        if lo <= d_max:
            at_least("ball_diameter", self.ball_diameter, lo,
                     f"with sensor_size {self.sensor_size:g} mm and gap {self.gap:g} mm, {why}")
        half = _bisect(lambda h: -well_top_skin(self.ball_radius, h, self.gap), 0.0, s2,
                       -WELL_TOP_SKIN)
        size_min = self.__dataclass_fields__["sensor_size"].metadata["lo"]
        size_max = 2 * (half - self.well_clearance) - 1e-4
        at_most("sensor_size", self.sensor_size, max(size_max, size_min),
                f"with ball_diameter {self.ball_diameter:g} mm and gap {self.gap:g} mm, {why}"
                + ("" if size_max >= size_min else "; even the smallest needs a smaller gap"))
        at_most("gap", self.gap, self.gap + well_top_skin(self.ball_radius, s2, self.gap)
                - WELL_TOP_SKIN - 1e-4, f"with ball_diameter {self.ball_diameter:g} mm and "
                f"sensor_size {self.sensor_size:g} mm, {why}")

    # ------------------------------------------------------------------------------ API
    def build(self) -> dict[str, Body]:
        """Bodies fingertip, base, cap (ABS), ball, bolt (steel), sensor_1..3 (cached)."""
        return dict(_build(self))

    def mesh_bodies(self) -> tuple[str, ...]:
        skin = ("skin",) if self.skin_thickness > 0 else ()
        return ("fingertip", *skin, "base", "cap")

    def well_floor_centers(self) -> np.ndarray:
        """(3, 3) centres of the well floors (where each sensor's back rests on the base)."""
        axes, _ = self.sensor_axes()
        return -self.well_depth * axes

    def named_faces(self, built: dict) -> dict[str, list]:
        """The facet sets this part can name by B-rep face (``{set: [(body, face), ...]}``,
        read by the gmsh mesher; :meth:`facet_sets` stays the fallback and names the rest): the
        ball seat (the fingertip body's sphere of the ball's radius) and the three well floors
        (the base's planes through each floor centre, facing along the sensor axis)."""
        from build123d import GeomType

        out = {"ball_seat": [("fingertip", f) for f in
                             built["fingertip"].shape.faces().filter_by(GeomType.SPHERE)
                             if abs(f.radius - self.ball_radius) < 1e-9]}
        axes, _ = self.sensor_axes()
        for k, (a, c) in enumerate(zip(axes, self.well_floor_centers())):
            out[f"sensor_well_{k + 1}"] = [
                ("base", f) for f in built["base"].shape.faces().filter_by(GeomType.PLANE)
                if np.dot(tuple(f.normal_at()), a) > 0.95
                and abs(np.dot(np.array(tuple(f.center())) - c, a)) < 1e-6]
        return {k: v for k, v in out.items() if v}

    def facet_sets(self) -> dict[str, FacetSelector]:
        """``ball_seat`` (fingertip's spherical seat), ``sensor_well_1..3`` (well floors: the
        sensors' reaction on the base, outward normal along the sensor axis), ``bolt_head``
        (annulus of the cap bottom under the bolt head), ``cap_mount`` (rest of the cap bottom,
        fixed to the robot), ``load_h*``/``load_r*`` (fingertip surface within
        ``load_patch_radius`` of each load point). The base-cap contact is an interface between
        two meshed bodies (not boundary), which the mesher names itself."""
        rb, tol = self.ball_radius, 0.05
        axes, _ = self.sensor_axes()
        floors = self.well_floor_centers()
        half = self.sensor_size / 2 + self.well_clearance + tol
        z_cb = self.cap_z[0]
        r_hole, r_cb = self.bolt_diameter / 2 + 0.2, self.head_diameter / 2

        def ball_seat(c, n):
            d = np.linalg.norm(c, axis=1)
            inward = -np.einsum("ij,ij->i", n, c) / np.maximum(d, 1e-12)
            return (np.abs(d - rb) < 0.15) & (c[:, 2] > -tol) & (inward > 0.7)

        def well(k):
            a, f = axes[k], floors[k]

            def sel(c, n):
                rel = c - f
                along = rel @ a
                lateral = np.linalg.norm(rel - np.outer(along, a), axis=1)
                return (n @ a > 0.95) & (np.abs(along) < tol) & (lateral < half * math.sqrt(2))
            return sel

        def bolt_head(c, n):
            rho = np.hypot(c[:, 0], c[:, 1])
            return (n[:, 2] < -0.95) & (np.abs(c[:, 2] - z_cb) < tol) & (rho > r_hole - tol) \
                & (rho < r_cb + tol)

        def cap_mount(c, n):
            rho = np.hypot(c[:, 0], c[:, 1])
            return (n[:, 2] < -0.95) & (np.abs(c[:, 2] - z_cb) < tol) & (rho > r_cb + 0.5)

        out = {"ball_seat": ball_seat, "bolt_head": bolt_head, "cap_mount": cap_mount}
        for k in range(3):
            out[f"sensor_well_{k + 1}"] = well(k)
        for name, (p, d) in self.load_points().items():
            out[f"load_{name}"] = _patch(p, d, self.load_patch_radius)
        return out

    def refinement(self) -> list[tuple[np.ndarray, float, float]]:
        """Ball seat, well floors, bolt-head seat and load patches."""
        out = [(np.zeros(3), self.ball_radius + 1.0, 0.6)]
        out += [(f, self.sensor_size / 2 + 1.0, 0.5) for f in self.well_floor_centers()]
        z_cb = self.cap_z[0]
        out.append((np.array([0.0, 0.0, z_cb]), self.head_diameter / 2 + 1.0, 0.5))
        out += [(p, self.load_patch_radius + 0.5, min(0.6, self.load_patch_radius / 2))
                for p, _ in self.load_points().values()]
        return out


def well_top_skin(ball_radius: float, s2: float, gap: float) -> float:
    """Height (mm) of the base's top face (``-gap``) above a sensor well's highest point in
    the base: the upper corner edge of the well's square section (half width ``s2``), which
    runs down and out along the sensor axis at SENSOR_ELEVATION_DEG, where it leaves the ball
    cavity (radius ``ball_radius + CAVITY_CLEARANCE``; the well's front face lies inside the
    cavity, :func:`_well_front`). Negative: the well cuts through the top face."""
    th = math.radians(SENSOR_ELEVATION_DEG)
    rc = ball_radius + CAVITY_CLEARANCE
    if rc <= s2:
        return -math.inf
    radial = math.sqrt(rc ** 2 - s2 ** 2)   # the corner's distance from the axis in its plane
    t = (radial - s2 * math.sin(th)) / math.cos(th)
    return -gap - (-t * math.sin(th) + s2 * math.cos(th))


def _bisect(f, lo: float, hi: float, target: float = WELL_TOP_SKIN) -> float:
    """Where the increasing ``f`` reaches ``target`` on [lo, hi] (to well below 1e-6 mm)."""
    for _ in range(80):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if f(mid) < target else (lo, mid)
    return hi


def _patch(point: np.ndarray, direction: np.ndarray, radius: float) -> FacetSelector:
    def sel(c, n):
        return (np.linalg.norm(c - point, axis=1) <= radius) & (n @ direction < -0.3)
    return sel


def _outline_solid(R: float, h: float, r: float):
    """Solid of revolution: cylinder of radius ``R`` and height ``h`` on ``z = 0`` whose top edge
    is rounded with radius ``r`` (``r = R``: hemispherical dome)."""
    # features below EPS are snapped away (no sliver edges); the outline moves by < EPS
    h = 0.0 if h < EPS else h
    r = 0.0 if r < EPS else (R if R - r < EPS else r)
    top = h + r
    edges = [Line((0, 0, 0), (R, 0, 0))]
    if h > 0:
        edges.append(Line((R, 0, 0), (R, 0, h)))
    if r > 0:  # quarter arc (R, h) -> (R - r, h + r), centre (R - r, h), in the XZ plane
        arc = CenterArc((0, 0, 0), r, 0, 90).rotate(Axis.X, 90).translate((R - r, 0, h))
        edges.append(arc)
    if R - r > 0:
        edges.append(Line((R - r, 0, top), (0, 0, top)))
    edges.append(Line((0, 0, top), (0, 0, 0)))
    return revolve(Face(Wire(edges)), Axis.Z, 360)


def _well_front(rb: float, rc: float, s2: float) -> float:
    """Where a sensor well (half width ``s2``) starts along its axis from the ball's centre:
    WELL_FRONT_INSET inside the ball's radius, or nearer the centre so that the well's front
    face lies a tenth of a millimetre inside the ball cavity (radius ``rc``) at every corner:
    a front face crossing the cavity's wall leaves a 45 deg wedge thinner than a wall there."""
    c = math.cos(math.radians(SENSOR_ELEVATION_DEG))
    return min(rb - WELL_FRONT_INSET, math.sqrt(max((rc - 0.1) ** 2 - s2 ** 2, 0.0)) / c - s2)


def _wire_hole(p: CantileverFingertip, rc: float, s2: float) -> tuple[float, float]:
    """``(radius, offset)`` of the wire hole in a well floor of half width ``s2``: offset (mm)
    from the floor's centre up its slope, so that the hole stays a nozzle's width (0.4 mm)
    outside the ball cavity (radius ``rc``) and inside the floor; the radius is WIRE_RADIUS, or
    what fits between the two (at least half of it)."""
    c = math.cos(math.radians(SENSOR_ELEVATION_DEG))
    cavity = (rc + 0.4 - p.well_depth * c) / c  # the cavity's wall + a nozzle, along the slope
    free = s2 - max(cavity, -s2)
    r = min(WIRE_RADIUS, max(free / 2, WIRE_RADIUS / 2))
    return r, max(0.0, cavity + r)


def _well_plane(p: CantileverFingertip, axis: np.ndarray) -> Plane:
    """Plane at the ball centre whose z points from the ball to the sensor (-axis) and whose x is
    horizontal."""
    z = -axis
    x = np.cross([0.0, 0.0, 1.0], z)
    return Plane(origin=(0, 0, 0), x_dir=tuple(x / np.linalg.norm(x)), z_dir=tuple(z))


@functools.lru_cache(maxsize=8)
def _build(p: CantileverFingertip) -> dict[str, Body]:
    rb = p.ball_radius
    inner = _outline_solid(p.fingertip_radius, p.h, p.r)
    fingertip = single_solid((inner - Sphere(rb)).clean(), "fingertip")
    skin = None
    if p.skin_thickness > 0:
        t = p.skin_thickness
        outer = _outline_solid(p.fingertip_radius + t, p.h, p.r + t)
        skin = single_solid((outer - inner).clean(), "skin")
    out = {"fingertip": Body("fingertip", fingertip, "ABS", (0.95, 0.6, 0.2))}
    out.update(_fixed_bodies(p))
    if skin is not None:  # cast silicone coating, not printed
        out["skin"] = Body("skin", skin, "silicone", (0.95, 0.85, 0.3), printed=False)
    return out


#: the bodies that do not depend on the fingertip's outline (h, r): built once per value of the
#: other parameters and shared (an (h, r) sweep rebuilds only the fingertip; same shapes)
_FIXED: dict[tuple, dict[str, Body]] = {}
_OUTLINE_ONLY = ("h", "r")


def _fixed_bodies(p: CantileverFingertip) -> dict[str, Body]:
    import dataclasses

    key = tuple((f.name, getattr(p, f.name)) for f in dataclasses.fields(p)
                if f.name not in _OUTLINE_ONLY)
    got = _FIXED.get(key)
    if got is None:
        if len(_FIXED) >= 8:
            _FIXED.pop(next(iter(_FIXED)))
        got = _FIXED[key] = _build_fixed(p)
    return got


def _build_fixed(p: CantileverFingertip) -> dict[str, Body]:
    """Base, cap, ball, bolt, sensors: they use neither h nor r."""
    rb = p.ball_radius
    axes, _ = p.sensor_axes()

    # ball with the tapped blind hole (modelled at the bolt's nominal diameter)
    rbolt = p.bolt_diameter / 2
    hole_len = p.bolt_top_z + rb
    ball_hole = Pos(0, 0, -rb + hole_len / 2 - 0.5) * Cylinder(rbolt, hole_len + 1.0)
    ball = single_solid((Sphere(rb) - ball_hole).clean(), "ball")

    # base: cylinder minus ball cavity, sensor wells, wire channels, bolt clearance hole
    z0, z1 = p.base_z
    base = Pos(0, 0, (z0 + z1) / 2) * Cylinder(p.base_radius, z1 - z0)
    rc = rb + CAVITY_CLEARANCE
    # cavity floor CAVITY_FLOOR_DROP below the ball's clearance: there the sensor wells' lower
    # faces cross it more steeply than in the shallow wedge (1.4 mm^2 thinner than the nozzle)
    # of a floor at the clearance (the printability check measures it over the area); 1.1 mm
    # keeps 83 % of each well's seat (deeper floors bite the seats); never closer than MIN_WALL
    # to the base's bottom
    floor = max(-(rc + CAVITY_FLOOR_DROP), z0 + MIN_WALL)
    base -= Pos(0, 0, (floor + z1 + 1) / 2) * Cylinder(rc, z1 + 1 - floor)
    side = p.sensor_size + 2 * p.well_clearance
    s2 = side / 2
    front = _well_front(rb, rc, s2)
    sensors = []
    for k, a in enumerate(axes):
        pl = _well_plane(p, a)
        depth = p.well_depth - front
        base -= pl * Pos(0, 0, front + depth / 2) * Box(side, side, depth)
        # wire channel: WIRE_DROP along the sensor axis through the well floor, then horizontal
        # and radial out through the wall, a ball at the bend. Each leg meets its face square
        # (the floor; the outer wall), and the hole sits up the floor's slope, a nozzle's width
        # outside the ball cavity (a horizontal channel out of the 45 deg floor, or a hole
        # crossing the cavity's wall at 45 deg, leaves a wedge thinner than a layer or a wall)
        r_wire, up = _wire_hole(p, rc, s2)
        slope = np.array([0.0, 0.0, 1.0]) - a[2] * a
        top = -p.well_depth * a + up * slope / np.linalg.norm(slope)
        bend = top - WIRE_DROP * a
        base -= Plane(origin=tuple(top - WIRE_DROP / 2 * a + 0.25 * a), z_dir=tuple(a)) * Cylinder(
            r_wire, WIRE_DROP + 0.5)
        base -= Pos(*bend) * Sphere(r_wire)
        radial = np.array([bend[0], bend[1], 0.0]) / math.hypot(bend[0], bend[1])
        start = math.hypot(bend[0], bend[1])
        length = p.base_radius + 1.0 - start
        base -= Plane(origin=tuple(np.array([0, 0, bend[2]]) + radial * (start + length / 2)),
                      z_dir=tuple(radial)) * Cylinder(r_wire, length)
        body = pl * Pos(0, 0, rb + p.button_radius + p.sensor_thickness / 2) * Box(
            p.sensor_size, p.sensor_size, p.sensor_thickness)
        button = pl * Pos(0, 0, rb + p.button_radius) * Sphere(p.button_radius)
        sensors.append(single_solid((body + button).clean(), f"sensor_{k + 1}"))
    zc0, zc1 = p.cap_z
    hole = Pos(0, 0, (zc0 - 1 + 0) / 2) * Cylinder(rbolt + 0.2, -zc0 + 1)
    base = single_solid((base - hole).clean(), "base")

    cap = Pos(0, 0, (zc0 + zc1) / 2) * Cylinder(p.base_radius, zc1 - zc0)
    cap = single_solid((cap - hole).clean(), "cap")

    z_head_top = zc0
    head = Pos(0, 0, z_head_top - p.head_height / 2) * Cylinder(p.head_diameter / 2, p.head_height)
    shank = Pos(0, 0, z_head_top + p.bolt_length / 2) * Cylinder(rbolt, p.bolt_length)
    bolt = single_solid((head + shank).clean(), "bolt")

    abs_c, steel, dark = (0.92, 0.9, 0.85), (0.75, 0.76, 0.78), (0.15, 0.15, 0.18)
    out = {
        "base": Body("base", base, "ABS", abs_c),
        "cap": Body("cap", cap, "ABS", (0.6, 0.6, 0.62)),
        "ball": Body("ball", ball, "steel", steel, printed=False),
        "bolt": Body("bolt", bolt, "steel", (0.5, 0.5, 0.55), printed=False),
    }
    for k, s in enumerate(sensors):
        out[f"sensor_{k + 1}"] = Body(f"sensor_{k + 1}", s, "steel", dark, printed=False)
    return out
