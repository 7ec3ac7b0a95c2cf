"""The material library as the Markdown table of docs/materials.md: each material's E, nu,
density, strength and relaxation, then where every value comes from.

    python examples/materials_table.py
"""

from designlab.fem.materials import material_table_markdown

if __name__ == "__main__":
    print(material_table_markdown(), end="")
