"""A printed cantilever load cell: a PLA beam clamped at one end, a foil strain gauge on its top
face near the clamp, weights hung at the tip.

    designlab predict examples/sensors/load_cell.py --out runs/load_cell
"""

from build123d import Box, Pos

import designlab as dl


class LoadCell(dl.SensorDefinition):
    name = "load_cell"
    description = "PLA cantilever with a foil strain gauge near the clamp"
    edge_length = 1.5

    length: float = dl.param(80.0, 20, 300, unit="mm", doc="beam length from the clamp")
    width: float = dl.param(12.0, 3, 60, unit="mm", doc="beam width")
    thickness: float = dl.param(4.0, 1, 20, unit="mm", doc="beam thickness")
    gauge_at: float = dl.param(12.0, 2, 150, unit="mm", doc="clamp to the gauge grid's centre")
    load_at: float = dl.param(75.0, 5, 300, unit="mm", doc="clamp to where the weights hang")
    material: str = dl.param("PLA", choices=("PLA", "ABS", "PETG", "PA12"),
                             doc="the beam's printed material")

    def bodies(self):
        beam = Pos(self.length / 2, 0, self.thickness / 2) * Box(
            self.length, self.width, self.thickness)
        return {"beam": dl.Solid(beam, self.material)}

    def supports(self):
        return [dl.Clamped(dl.Face("beam", normal=(-1, 0, 0)))]

    def transducers(self):
        top = dl.Face("beam", normal=(0, 0, 1))
        # a 3 mm x 1.6 mm foil grid along the beam (e.g. a 120 ohm, GF 2.0 general-purpose gauge)
        return [dl.StrainGauge("gauge", top, center=(self.gauge_at, 0, self.thickness),
                               direction=(1, 0, 0), length_mm=3.0, width_mm=1.6,
                               gauge_factor=2.0)]

    def loads(self):
        # the weights hang from a 3 mm pad of the top face centred at load_at
        x, w, t = self.load_at, self.width, self.thickness
        pad = dl.Face("beam", normal=(0, 0, 1), box=((x - 1.5, -w, t - 0.1), (x + 1.5, w, t + 0.1)))
        return [dl.LoadPoint("tip", pad, at=(x, 0, t))]

    def protocol(self):
        return dl.Staircase("tip", weights_g=(50, 100, 150, 200, 250, 300), hold_s=10.0)
