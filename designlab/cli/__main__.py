"""``python -m designlab.cli``: the ``designlab`` command."""

from designlab.cli.app import main

main()
