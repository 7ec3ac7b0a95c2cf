"""Build the three parametric parts at their paper defaults (plus the tested fingertip of seed 001
Table II), print their bodies, closed-form checks and build times, and save coloured assemblies.

    /work/venv/bin/python examples/parts_gallery.py [OUT_DIR]   # default: parts_gallery/

Units mm, mm^3, s. Each part is built once in this process (the first build is what is timed).
:func:`render_parts` writes a PNG of each part (``python scripts/gallery.py`` puts them in
``docs/img/`` for docs/gallery.md and docs/parts.md).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from designlab.geometry.assembly import assembly, save_assembly_gltf, save_assembly_step
from designlab.geometry.fingertip import CantileverFingertip
from designlab.geometry.flexure import SpringFlexure
from designlab.geometry.solids import volume
from designlab.geometry.strap import ArchStrap


def gallery_parts() -> dict:
    """The parts of the gallery: the three defaults and the tested fingertip of Table II."""
    return {"strap": ArchStrap(), "fingertip": CantileverFingertip(),
            "fingertip_tested": CantileverFingertip.tested(), "flexure": SpringFlexure()}


def render_parts(out: Path, size: tuple[int, int] = (640, 480)) -> list[Path]:
    """A PNG per gallery part, ``out/part_<name>.png`` (bodies coloured, bought parts
    see-through); returns the paths."""
    from designlab.geometry.render import render_bodies

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, part in gallery_parts().items():
        paths.append(out / f"part_{name}.png")
        render_bodies(part.build(), paths[-1], size=size, title=type(part).__name__)
    return paths


def main(out: Path) -> None:
    parts = gallery_parts()
    print(f"{'part':18s} {'body':12s} {'material':10s} {'printed':7s} {'volume mm^3':>12s}")
    for name, part in parts.items():
        t0 = time.perf_counter()
        bodies = part.build()
        dt = time.perf_counter() - t0
        for b in bodies.values():
            print(f"{name:18s} {b.name:12s} {b.material:10s} {str(b.printed):7s} "
                  f"{volume(b.shape):12.3f}")
        print(f"{name:18s} build {dt:.2f} s; meshed bodies: {', '.join(part.mesh_bodies())}")
        a = assembly(part, name=name)
        save_assembly_step(a, out / f"{name}.step")
        save_assembly_gltf(a, out / f"{name}.glb")
    s, f, x = parts["strap"], parts["fingertip"], parts["flexure"]
    b = s.build()
    filled = sum(volume(b[n].shape) for n in s.mesh_bodies())
    print(f"strap + traces {filled:.4f} mm^3 vs slotted outline x thickness "
          f"{s.outline_area() * s.thickness:.4f}")
    print(f"spring {volume(x.build()['spring'].shape):.3f} mm^3 vs closed form "
          f"{x.wire_volume():.3f}; free length {x.length:.3f} mm (paper 19.8)")
    print(f"fingertip total height {f.total_height:g} mm (Table III: 20), tested "
          f"{parts['fingertip_tested'].total_height:g} mm (Table II: 48.5)")
    print(f"assemblies written to {out}/")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("parts_gallery"))
