"""Which drawing process gets which plots in ``designlab predict --out`` (predict_and_write):
the groups that read only the run's report go out before the report is finished, one to each
process; the rest after, to the process with fewer groups; none early with a loop model or
with one drawing process. (That the files are the same as one process draws them:
tests/predict/test_predict_parallel.py.)"""

import dataclasses
from pathlib import Path

from designlab.sensors import get_sensor
from designlab.predict.run import _early_plots, _late_plots
from designlab.predict.side import _Pictures

#: the fingertip's plot groups and one that needs ``finish`` (the routing of a late group)
FINGERTIP = dataclasses.replace(get_sensor("fingertip"), plot_groups=(
    *get_sensor("fingertip").plot_groups, ("after_finish.png",)))


class _Recorder:
    """A drawing process that records the plot groups it is sent."""

    _dead = False

    def __init__(self):
        self.groups = []

    def submit(self, job, *args):
        self.groups.append(args[-1])
        return len(self.groups)


def _pictures(two: bool = True) -> _Pictures:
    return _Pictures(painter=_Recorder(), side=_Recorder() if two else None,
                     plot_dir=Path("/nonexistent"))


def test_report_only_groups_go_early_one_to_each_process():
    pics = _pictures()
    early = _early_plots(FINGERTIP, pics, "fingertip", None, {}, None)
    assert [g for _, g, _ in early] == [g for g in FINGERTIP.plot_groups
                                        if set(g) <= FINGERTIP.plots_before_finish]
    assert len(early) == 2 and early[0][0] is pics.painter and early[1][0] is pics.side
    plots = _late_plots(FINGERTIP, pics, "fingertip", None, {}, early)
    # every group once, the one that needs finish after, drawn by the coarse mesh's process
    # (tie: the painter also renders deformed.png)
    assert [g for g, _ in plots] == list(FINGERTIP.plot_groups)
    assert pics.side.groups[-1] == ("after_finish.png",)
    drawn = [n for g in pics.painter.groups + pics.side.groups for n in g]
    assert sorted(drawn) == sorted(n for g in FINGERTIP.plot_groups for n in g)


def test_no_early_plots_with_a_loop_model_or_one_process():
    for pics, model in ((_pictures(), "model.json"), (_pictures(two=False), None)):
        assert _early_plots(FINGERTIP, pics, "fingertip", None, {}, model) == []
    pics = _pictures(two=False)
    plots = _late_plots(FINGERTIP, pics, "fingertip", None, {}, [])
    assert plots == [(None, 1)] and pics.painter.groups == [None]   # one call draws all


def test_late_plots_after_the_second_process_died():
    pics = _pictures()
    early = _early_plots(FINGERTIP, pics, "fingertip", None, {}, None)
    pics.side._dead = True              # the plotter is the painter from now on
    plots = _late_plots(FINGERTIP, pics, "fingertip", None, {}, early)
    assert [g for g, _ in plots] == list(FINGERTIP.plot_groups)     # no group twice
    assert pics.painter.groups[-1] == ("after_finish.png",)
