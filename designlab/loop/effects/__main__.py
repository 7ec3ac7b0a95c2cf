"""``python -m designlab.loop.effects``: print the effect table of docs/loop.md."""

from designlab.loop.effects import effects_table

print(effects_table())
