"""docs/gallery.md is the page ``scripts/gallery.py`` writes, every image it (and the README and
docs/parts.md) links exists, and the committed images stay small."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
IMAGE_LINK = re.compile(r"!\[[^\]]*\]\(([^)\s]+)\)")


def _gallery():
    spec = importlib.util.spec_from_file_location("gallery", ROOT / "scripts" / "gallery.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod      # dataclasses look their module up there
    spec.loader.exec_module(mod)
    return mod


def test_gallery_page_is_the_generated_one():
    page = (ROOT / "docs" / "gallery.md").read_text(encoding="utf-8")
    assert page == _gallery().gallery_page(), "run: python scripts/gallery.py --page-only"


def test_every_image_the_gallery_links_exists_and_is_a_png():
    page = (ROOT / "docs" / "gallery.md").read_text(encoding="utf-8")
    links = IMAGE_LINK.findall(page)
    assert len(links) == len(_gallery().ENTRIES) >= 8
    for link in links:
        f = ROOT / "docs" / link
        assert f.is_file(), f"docs/gallery.md links {link}, which does not exist"
        assert f.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", link


def test_every_section_names_the_command_that_makes_its_images():
    g = _gallery()
    page = (ROOT / "docs" / "gallery.md").read_text(encoding="utf-8")
    for title, command, _ in g.JOBS.values():
        assert f"## {title}" in page and f"`{command}`" in page
    assert "python scripts/gallery.py" in page


def test_images_linked_from_readme_and_docs_exist():
    for md in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for link in IMAGE_LINK.findall(md.read_text(encoding="utf-8")):
            if link.startswith(("http://", "https://")):
                continue
            assert (md.parent / link).is_file(), f"{md.relative_to(ROOT)} links {link}"


def test_committed_images_stay_small():
    sizes = {p.name: p.stat().st_size for p in (ROOT / "docs" / "img").glob("*.png")}
    assert sizes and sum(sizes.values()) < 500_000, sizes
    assert max(sizes.values()) < 100_000, sizes


def test_shrink_scales_and_quantizes(tmp_path):
    from PIL import Image

    src = tmp_path / "big.png"
    Image.new("RGB", (1500, 300), (200, 10, 10)).save(src)
    out = _gallery().shrink(src, tmp_path / "small.png")
    im = Image.open(out)
    assert im.size == (720, 144) and im.mode == "P"
