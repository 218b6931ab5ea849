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

RESULTS = Path(__file__).resolve().parent.parent / "bench" / "results"


def on_files(files: Files, config: MkDocsConfig) -> Files:
    for plot in sorted(RESULTS.glob("*.png")):
        files.append(File.generated(config, f"results/{plot.name}", abs_src_path=str(plot)))
    return files
