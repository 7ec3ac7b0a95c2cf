"""A printed six-axis force/torque sensor read by optical fork interrupters: four spiral arms
join a hub (robot side) to an outer ring (tool side); eight fins on the tool side cut the beams
of eight TCST1103 forks on the robot side with their 45-degree edges. Calibrated with hanging
masses: five mass positions in twelve orientations (60 load states).

    designlab predict examples/sensors/printed_ft.py --out runs/printed_ft

Frames. The geometry is described in T (CAD: origin at the centre of the print-bed face, +z_T
toward the robot); the loads are labelled in S (x_S = x_T, y_S = -y_T, z_S = -z_T, a turn of
180 degrees about x, so the spiral keeps its handedness). The bodies are built in T and turned
into S, so the mesh, the load point and every reported load are in S, as the labels are.

Simplifications (each stated where it is made): the M4 bores are left out (the hub is clamped
on its top face, z_T = 18); the fin ring is cut down to the pads under the fins; the fins are
straight along the tangent at their middle; the arc ends are bridged into the blocks within the
blocks' radial faces (the free arc -36.7..83.2 deg leaves gaps of up to about 1 mm to them).
"""

from math import cos, radians, sin

import numpy as np
from build123d import Box, Compound, Cylinder, Polygon, Pos, Rot, extrude

import designlab as dl

H_ARM = 14.0          # arm and block height, mm (z_T 0..14)
R_FIN = 43.5          # fins' and forks' radius, mm
FIN_Z0 = 16.5         # fin ring top = fin foot, z_T mm
EDGE_Z = (17.5, 21.5)  # the 45-degree edge's foot and top, z_T mm (height 1.0 at 6.0, 5.0 at 2.0)
#: TCST1103: 10-90 % of the signal over about 0.6 mm of edge travel; assumed to span the 10-bit
#: ADC's full range (1023 counts), read at mid-slope: 0.8 x 1023 counts / 0.6 mm
GAIN_COUNTS_PER_MM = 0.8 * 1023 / 0.6


def to_s(v):
    """A point or direction of frame T in frame S."""
    return (float(v[0]), -float(v[1]), -float(v[2]))


def sector(c, r_in, r_out, a0, a1, h):
    """The piece of an annulus about centre c (x, y) between angles a0..a1 (deg), z_T 0..h."""
    ring = Pos(c[0], c[1], h / 2) * (Cylinder(r_out, h) - Cylinder(r_in, h))
    a0, a1 = min(a0, a1), max(a0, a1)     # counter-clockwise: the polygon faces +z
    n = max(4, int((a1 - a0) / 5) + 1)
    rim = [(c[0] + 2 * r_out * cos(radians(a)), c[1] + 2 * r_out * sin(radians(a)))
           for a in np.linspace(a0, a1, n)]
    return ring & extrude(Polygon(c, *rim, align=None), h)


def polar_box(r, theta, turn, dr, dt, h, z0=0.0):
    """A box dr (radial) x dt (tangential) x h centred at (r, theta), turned ``turn`` deg."""
    return Rot(0, 0, theta) * Pos(r, 0, z0 + h / 2) * Rot(0, 0, turn) * Box(dr, dt, h)


class PrintedFT(dl.SensorDefinition):
    name = "printed_ft"
    description = "printed six-axis F/T sensor: four spiral arms, eight optical fork channels"
    source = "TAMS printed F/T sensor (adjustable variant), as described in a third-party rebuild"
    edge_length = 5.0
    #: moments scaled by this length (mm) in condition_number_scaled: the pockets' reach
    moment_scale_mm = 55.0
    #: the row-normalised sensitivity (each channel divided by its Fz entry) does not depend on
    #: the forks' unknown gains
    normalise_rows_by = "Fz"

    # 2.0 to 3.5 mm: the 0.9 mm gap between neighbouring arms closes at 3.9 mm; below 2.0 the
    # bridges into the outer blocks (cut at r 38.1) thin out
    arm_width: float = dl.param(3.0, 2.0, 3.5, unit="mm", doc="spiral arm width in the plane "
                                "(about its mean radius 37.0 mm)")
    arm_height: float = dl.param(14.0, 6.0, 14.0, unit="mm", doc="spiral arm height (z_T from 0)")
    material: str = dl.param("PLA", choices=("PLA", "ABS"), doc="printed material (not stated by "
                             "the source)")
    clamp: str = dl.param("face", choices=("face", "bolts"), doc="robot side held on the hub's "
                          "whole top face or only at the four clamping bolts")
    arm_edge: float = dl.param(3.0, 0.5, 10.0, unit="mm", doc="mesh edge length in the arms")
    operating_point: float = dl.param(0.5, 0.1, 0.9, doc="where along the 45-degree edge each "
                                      "beam reads (0 foot, 1 top): set by the fin ring's screws")
    gain: float = dl.param(GAIN_COUNTS_PER_MM, 1.0, 1e5, unit="counts/mm", doc="each fork's "
                           "reading per mm of edge rise (10-90 % over 0.6 mm on a 10-bit ADC)")
    noise: float = dl.param(1.0, 0.0, 100.0, unit="counts", doc="noise of one held reading "
                            "(one ADC count rms: quantisation and electrical noise)")

    def _arms(self):
        r_in, r_out = 37.0 - self.arm_width / 2, 37.0 + self.arm_width / 2
        out = []
        for k in range(4):
            th = 90.0 * k
            c = (cos(radians(th)) * 1.0 - sin(radians(th)) * -2.7,
                 sin(radians(th)) * 1.0 + cos(radians(th)) * -2.7)
            arc = sector(c, r_in, r_out, th - 36.7, th + 83.2, self.arm_height)
            # the cut ends stop short of the blocks: bridge them inside the blocks' radial faces
            start = sector(c, r_in, r_out, th - 44.0, th - 36.0, self.arm_height) - Cylinder(
                38.1, 60)
            end = sector(c, r_in, r_out, th + 82.0, th + 92.0, self.arm_height) & Pos(
                0, 0, H_ARM / 2) * Cylinder(35.3, H_ARM)
            out += [arc, start, end]
        return out

    def bodies(self):
        hub = Pos(0, 0, 9) * (Cylinder(32.5, 18) - Cylinder(20, 18))
        ring = Pos(0, 0, 7.5) * (Cylinder(52, 15) - Cylinder(42, 15))
        parts = [hub] + self._arms()
        for k in range(4):
            th = 90.0 * k
            parts.append(polar_box(40.55, th - 45, 2, 4.9, 8.0, H_ARM))
            parts.append(polar_box(33.4, th, 6, 3.8, 9.0, H_ARM))
        # one fuse of every piece (one boolean, not one per piece), then the ring cut away:
        # the outer blocks reach 1 mm into the ring
        element = parts[0].fuse(*parts[1:]).clean() - ring
        carrier = Compound([self._fin(k, s) for k in range(4) for s in (1, -1)])
        turn = Rot(180, 0, 0)   # T -> S
        return {"element": dl.Solid(turn * element, self.material),
                "ring": dl.Solid(turn * ring, self.material),
                "fins": dl.Solid(turn * carrier, self.material)}

    def _fin(self, k, s):
        """Fin of site (module k, side s = +1 / -1) with its pad of the fin ring (1.5 thick,
        from 0.75 mm off the module axis to 8 mm, r 42..46): straight along the tangent at the
        fin's middle; profile (tangential u from the fin's start, z_T): 5.0 high up to u = 2.0,
        then the 45-degree edge down to 1.0 at u = 6.0."""
        phi = 90.0 * k + s * (1.0 + np.degrees(3.0 / R_FIN))   # the fin's middle
        prof = Polygon((0, 0), (6, 0), (6, 1), (2, 5), (0, 5), align=None)
        fin = extrude(prof, 1.0)                                # u-z profile, 1.0 thick along +z
        # local (u, z, radial) -> T: u tangential (away from the axis), radial outward
        fin = Pos(0, 0, FIN_Z0) * Rot(90, 0, 0) * Pos(0, 0, -0.5) * fin  # u = x, z_T = z, r = -y
        fin = Rot(0, 0, phi) * Pos(R_FIN, 0, 0) * Rot(0, 0, 90 * s) * Pos(-3, 0, 0) * fin
        pad = sector((0, 0), 42.0, 46.0, 90.0 * k + s * np.degrees(0.75 / 42.0),
                     90.0 * k + s * np.degrees(8.0 / 42.0), 1.5)
        return fin + Pos(0, 0, 15.0) * pad

    def supports(self):
        # robot side: the hub's top face (z_T = 18) clamped to the upper ring and the robot
        # adapter, taken as rigid; "bolts": only 9 x 9 mm patches at the four clamping bores
        # (22.5 + 90 k deg, r 28.2), the hub free to deform between them (a bound on the
        # robot side's compliance and a low bolt preload)
        top = to_s((0, 0, 1))
        if self.clamp == "face":
            return [dl.Clamped(dl.Face("element", normal=top))]
        out = []
        for k in range(4):
            a = radians(22.5 + 90.0 * k)
            c = to_s((28.2 * cos(a), 28.2 * sin(a), 18.0))
            box = ((c[0] - 4.5, c[1] - 4.5, c[2] - 0.5), (c[0] + 4.5, c[1] + 4.5, c[2] + 0.5))
            out.append(dl.Clamped(dl.Face("element", normal=top, box=box)))
        return out

    def sites(self):
        """(name, site angle deg, side s, tangential direction away from the module axis) in T."""
        out = []
        for k, axis in enumerate(("+x", "+y", "-x", "-y")):
            for s in (1, -1):
                a = radians(90.0 * k + s * 5.0)
                out.append((f"{axis}{'+' if s > 0 else '-'}", a, s,
                            (-s * sin(a), s * cos(a), 0.0)))
        return out

    def transducers(self):
        z = EDGE_Z[0] + self.operating_point * (EDGE_Z[1] - EDGE_Z[0])
        out = []
        for name, a, s, t in self.sites():
            # the edge's point at the beam's height, on the fin's tangent through its middle
            phi = radians(90.0 * round(np.degrees(a) / 90.0) + s * (1.0 + np.degrees(3 / R_FIN)))
            u = 2.0 + (EDGE_Z[1] - z)                      # from the fin's start
            e_t = np.array([-s * sin(phi), s * cos(phi), 0.0])
            p = R_FIN * np.array([cos(phi), sin(phi), 0.0]) + (u - 3.0) * e_t + (0, 0, z)
            lo, hi = to_s(p - 1.2), to_s(p + 1.2)
            box = (tuple(np.minimum(lo, hi)), tuple(np.maximum(lo, hi)))
            edge = dl.Face("fins", normal=to_s((e_t + (0, 0, 1)) / np.sqrt(2)), box=box)
            # edge rise = dz_T + dt_away: the direction (t_away + z_T), not normalised
            out.append(dl.DisplacementProbe(f"fork_{name}", edge, to_s(np.add(t, (0, 0, 1))),
                                            noise=self.noise, gain=self.gain, unit="counts"))
        return out

    def loads(self):
        # the calibration jig bolted to the outer ring's z_T = 0 face; moments about S's origin
        return [dl.LoadPoint("jig", dl.Face("ring", normal=to_s((0, 0, -1))), at=(0, 0, 0))]

    def refinement(self):
        # the arms: spheres of edge arm_edge along each arc
        out = []
        for k in range(4):
            th = 90.0 * k
            c = np.array([cos(radians(th)) + 2.7 * sin(radians(th)),
                          sin(radians(th)) - 2.7 * cos(radians(th)), 7.0])
            for a in np.linspace(th - 40, th + 88, 12):
                p = c + 37.0 * np.array([cos(radians(a)), sin(radians(a)), 0.0])
                out.append((np.array(to_s(p)), 7.5, self.arm_edge))
        return out

    def protocol(self):
        # five mass positions (in S): the empty jig, then jig + cylinder + cap in pockets 1-4
        pockets = ((1, 1), (-1, 1), (-1, -1), (1, -1))
        masses = [0.309] + [1.028] * 4
        cogs = [(0.0, 0.0, 45.0)] + [(29.37 * a, 29.37 * b, 53.94) for a, b in pockets]
        gravity = [(0, 0, -1), (0, 0, 1), (1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0),
                   (0.865, 0.251, -0.434), (0.901, 0.252, -0.352), (0.501, 0.708, -0.498),
                   (0.718, 0.030, 0.695), (-0.434, -0.866, -0.247), (-0.866, -0.353, 0.353)]
        return dl.Wrenches.from_masses("jig", masses, cogs, gravity, hold_s=15.0)
