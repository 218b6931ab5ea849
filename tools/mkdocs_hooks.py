"""mkdocs hooks for the docs site (mkdocs.yml ``hooks:``).

The results pages (docs/results/) include ``bench/results/*.md`` with pymdownx.snippets, and
those files show their plots by bare name (``![...](detector_recall_by_height.png)``), as they
must to read well on GitHub beside the plot. The plots are served from their one home rather
than copied into docs/: each ``bench/results/*.png`` is added to the site as ``results/NAME.png``,
where the including pages resolve the bare names.
"""

from __future__ import annotations

from pathlib import Path

from mkdocs.config.defaults import MkDocsConfig
from mkdocs.structure.files import File, Files
from mkdocs.structure.pages import Page

RESULTS = Path(__file__).resolve().parent.parent / "bench" / "results"


def on_files(files: Files, config: MkDocsConfig) -> Files:
    for plot in sorted(RESULTS.glob("*.png")):
        files.append(File.generated(config, f"results/{plot.name}", abs_src_path=str(plot)))
    return files


def on_page_content(html: str, page: Page, config: MkDocsConfig, files: Files) -> str:
    """An included results file brings its own ``#`` title; the theme lists only what sits under
    the page's first title in the table of contents, so the included titles (and their sections)
    are moved under it: every included file shows up in the page's contents."""
    items = page.toc.items
    if len(items) > 1:
        items[0].children.extend(items[1:])
        del items[1:]
    return html
