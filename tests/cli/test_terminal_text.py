"""User text (paths, file names) on the terminal: control characters shown as escapes, rich
markup in names printed literally."""

from __future__ import annotations

from designlab.cli.app import console


def test_an_esc_in_printed_text_is_shown_not_sent(capsys):
    console.print("open next: a\x1b[31mred/mesh.vtu", markup=False, highlight=False)
    out = capsys.readouterr().out
    assert "\x1b" not in out and "a\\x1b[31mred/mesh.vtu" in out


def test_a_markup_like_file_name_in_the_mesh_table_is_literal(capsys):
    from designlab.cli.parts import _mesh_table

    rep = {"n_cells": 4, "n_points": 10, "dof": 30, "seconds": 0.1, "mesher": "tetwild",
           "regions": {"[/bold]": {"cells": 4, "volume_mm3": 1.0, "body_mm3": 1.0,
                                   "body_volume_mm3": 1.0, "volume_error_percent": 0.0}},
           "materials": {"[/bold]": "ABS"}}
    console.print(_mesh_table("[/bold].stl", 2, rep))
    assert "[/bold]" in capsys.readouterr().out
