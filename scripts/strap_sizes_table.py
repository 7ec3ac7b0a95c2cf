"""The strap-size tables of the user guide (docs/guide/strap_sizes.md): 5 sizes and ``--sizes
auto`` for all adults of the shipped table, each with the paper's three slots beside them, the size
count ``--sizes auto`` picks per population, fitted by perimeter and by breadth, and how the
depth assumption moves them.

    python scripts/strap_sizes_table.py > /tmp/strap_sizes.md
"""

from __future__ import annotations

from designlab.errors import ParameterError
from designlab.sensors.strap import population as pp
from designlab.sensors.strap import sizes as sz
from designlab.sensors.strap.fit import default_target

FINGERS, SEED = 1000, 0


def auto_rows() -> list[str]:
    """``--sizes auto`` per population, fit and depth assumption (no FEM: strains only)."""
    target = default_target()
    rows = ["| population | depth ratio (mean, sd) | fitted by | auto sizes | share within "
            "10 % | paper slots: share within, slack |", "|---|---|---|---|---|---|"]
    depths = (pp.DepthAssumption(), pp.DepthAssumption(mean=0.70, sd=0.05),
              pp.DepthAssumption(mean=1.00, sd=0.05), pp.DepthAssumption(sd=0.0))
    for group in pp.GROUPS:
        for depth in depths if group == "all" else depths[:1]:
            pop = pp.draw(group, FINGERS, SEED, depth=depth)
            from designlab.fem.materials import get_material

            slots = sz.paper_slots(pop, target, get_material("PI-ETPU"), None)
            paper = (f"{100 * slots['share_within_goal']:.1f} %, "
                     f"{100 * slots['slack_share']:.1f} %")
            for fit_by in sz.FIT_BY:
                try:
                    n, tried = sz.auto_count(pop, target, fit_by)
                    got = (str(n), f"{100 * tried[-1]['share_within_goal']:.1f} %")
                except ParameterError:
                    got = (f"none up to {sz.MAX_SIZES}", "-")
                rows.append(f"| {group} | {depth.mean:g}, {depth.sd:g} | {fit_by} | {got[0]} | "
                            f"{got[1]} | {paper} |")
    return rows


def main() -> None:
    pop = pp.draw("all", FINGERS, SEED)
    for sizes in (5, "auto"):
        print(sz.markdown(sz.strap_sizes(pop, sz.SizesRequest(sizes=sizes))))
    print("\n".join(auto_rows()))


if __name__ == "__main__":
    main()
