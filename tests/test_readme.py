"""The README and docs hold together: linked files exist, images are committed and small,
headings that links name exist, and every public plotting function is listed."""
import re
import subprocess
from pathlib import Path

import pytest

import jaxdda.viz

pytestmark = pytest.mark.smoke  # no compilation

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
MAX_IMAGE_BYTES = 200_000
LINK = re.compile(r"(!?)\[[^\]]*\]\(([^)\s]+)\)")


def prose(page: Path) -> str:
    """The page without code blocks and inline code (they may hold brackets)."""
    text = re.sub(r"^```.*?^```", "", page.read_text(), flags=re.S | re.M)
    return re.sub(r"`[^`\n]*`", "", text)


def links(page: Path) -> list[tuple[bool, str]]:
    """(is an image, target) of every relative link on the page."""
    return [(bang == "!", target) for bang, target in LINK.findall(prose(page))
            if not re.match(r"[a-z]+:", target) and not target.startswith("#")]


def anchors(page: Path) -> set[str]:
    """GitHub's anchors of the page's headings: lower case, punctuation dropped, spaces -."""
    titles = re.findall(r"^#+\s+(.*?)\s*$", prose(page), flags=re.M)
    return {re.sub(r"[^\w\- ]", "", t.lower()).replace(" ", "-") for t in titles}


ALL_LINKS = [(page, image, target) for page in PAGES for image, target in links(page)]
IMAGES = [(page, target) for page, image, target in ALL_LINKS if image]


def test_pages_have_links():
    assert len(ALL_LINKS) > 10 and IMAGES  # the parsing finds what is there


@pytest.mark.parametrize("page, image, target", ALL_LINKS, ids=[f"{p.name}:{t}" for p, _, t in ALL_LINKS])
def test_relative_link_points_at_a_file(page, image, target):
    path, _, anchor = target.partition("#")
    file = (page.parent / path).resolve()
    assert file.is_file(), f"{page.name} links {target}, which is missing"
    if anchor and file.suffix == ".md":
        assert anchor in anchors(file), f"{page.name} links {target}: no such heading in {path}"


@pytest.mark.parametrize("page, target", IMAGES, ids=[t for _, t in IMAGES])
def test_image_is_committed_and_small(page, target):
    file = (page.parent / target).resolve()
    ignored = subprocess.run(["git", "check-ignore", "-q", "--no-index", str(file)], cwd=ROOT)
    assert ignored.returncode == 1, f"{target} is git-ignored, so it would not be committed"
    tracked = subprocess.run(["git", "ls-files", "--error-unmatch", str(file)], cwd=ROOT, capture_output=True)
    assert tracked.returncode == 0, f"{target} is not committed"
    assert file.stat().st_size < MAX_IMAGE_BYTES


@pytest.mark.parametrize("name", jaxdda.viz.__all__)
def test_plotting_function_is_in_readme(name):
    assert f"{name}(" in (ROOT / "README.md").read_text() or f"`{name}`" in (ROOT / "README.md").read_text()
