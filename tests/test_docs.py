"""The docs site stays true to the code: every module path it cites exists, and the
architecture page's layering tables are the rules ``tests/test_layering.py`` enforces.

(``make docs`` builds the site with ``--strict``, which catches broken links between pages and
missing ``bench/results`` includes; it cannot know which source paths exist.)
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.test_layering import MODELS_ALLOWED, SERVICE_ALLOWED

ROOT = Path(__file__).resolve().parents[1]
PAGES = [*sorted((ROOT / "docs").rglob("*.md")), ROOT / "README.md", ROOT / "CONTRIBUTING.md"]
PATH = re.compile(
    r"\b((?:service|models|capture|common|bench|tools|tests|examples|docker|docs)/[\w./-]*\w)"
)
MODULE = re.compile(r"\b((?:service|models|capture|common|bench)(?:\.[a-z_0-9]+)+)")
ARCHITECTURE = ROOT / "docs" / "development" / "architecture.md"


def cited_paths(text: str) -> set[str]:
    return set(PATH.findall(text))


def module_exists(dotted: str) -> bool:
    """``service.tracking.tracker`` names a module; ``service.tracking.tracker.RECOMMENDED`` a
    module and a name its source defines."""
    parts = dotted.split(".")
    for end in (len(parts), len(parts) - 1):
        base = ROOT.joinpath(*parts[:end])
        for source in (base.with_suffix(".py"), base / "__init__.py"):
            if source.exists():
                return end == len(parts) or parts[-1] in source.read_text()
    return False


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_cited_path_exists(page: Path) -> None:
    text = page.read_text()
    missing = sorted(p for p in cited_paths(text) if not (ROOT / p).exists())
    missing += sorted(m for m in set(MODULE.findall(text)) if not module_exists(m))
    assert not missing, f"{page.relative_to(ROOT)} cites what does not exist: {missing}"


def test_path_check_sees_a_missing_module() -> None:
    text = "see `service/tracking/nowhere.py` and `service.nowhere.module`"
    assert [p for p in cited_paths(text) if not (ROOT / p).exists()]
    assert not module_exists("service.nowhere.module")
    assert not module_exists("service.tracking.tracker.NOWHERE")
    assert module_exists("service.tracking.tracker.RECOMMENDED")


def layering_table(name: str) -> dict[str, set[str]]:
    text = ARCHITECTURE.read_text()
    block = text.split(f"<!-- layering:{name} -->")[1].split(f"<!-- /layering:{name} -->")[0]
    rules: dict[str, set[str]] = {}
    for line in block.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 2 or not cells[0].startswith("`"):
            continue
        rules[cells[0].strip("`")] = set(re.findall(r"`(\w+)`", cells[1]))
    return rules


@pytest.mark.parametrize(
    ("name", "rules"), [("service", SERVICE_ALLOWED), ("models", MODELS_ALLOWED)]
)
def test_architecture_page_states_the_layering_rules(name: str, rules: dict[str, set[str]]) -> None:
    assert layering_table(name) == rules


def test_readme_stays_short_and_shows_the_two_commands() -> None:
    """User docs grow in docs/, not in the README (issue 24: it was 1,373 lines)."""
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 200
    assert "make demo" in readme and "make test" in readme


def test_every_results_file_is_on_the_site() -> None:
    """A new bench/results/*.md is included by a docs page (``--8<--``), or nobody reads it."""
    included = {
        name
        for page in (ROOT / "docs").rglob("*.md")
        for name in re.findall(r'^--8<-- "bench/results/([\w.-]+\.md)"', page.read_text(), re.M)
    }
    on_disk = {path.name for path in (ROOT / "bench" / "results").glob("*.md")}
    assert not on_disk - included, f"results not included by any docs page: {on_disk - included}"
