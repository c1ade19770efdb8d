"""Sphinx configuration of the tactile_sensor documentation: MyST Markdown pages.

``make docs`` builds this folder with warnings as errors; on a robot rosdoc2 builds the same
folder (``tactile_sensor/rosdoc2.yaml`` points its Sphinx builder here). rosdoc2 runs this
file from a folder of its own, so nothing here depends on this file's location.
"""

project = "tactile_sensor"
author = "tactile_sensor maintainers"
copyright = "tactile_sensor maintainers"

extensions = ["myst_parser"]
source_suffix = {".md": "markdown"}
root_doc = "index"
# _generated: the figures and their captions make docs draws (benchmarks/docs_figures.py),
# included by the workflow pages, not pages of their own
exclude_patterns = ["_build", "_generated"]


def _figure_placeholders() -> None:
    """A build that did not run the figure step first (rosdoc2 on a robot) says where the
    figures come from instead of failing on the pages' includes."""
    from pathlib import Path

    generated = Path(__file__).resolve().parent / "_generated"
    pages = ("ambient", "array", "bench-calibration", "benchmarks", "design-studies",
             "gripper-slip", "gripper-workflow", "rate-calibration", "recordings")
    for page in pages:
        target = generated / f"{page}.md"
        if not target.is_file():
            generated.mkdir(exist_ok=True)
            target.write_text("*The figure is drawn by `make docs` from the committed benchmark "
                              "results (`benchmarks/docs_figures.py`); this build did not run "
                              "it.*\n", encoding="utf-8")


_figure_placeholders()

# Section links such as [text](gripper-outcomes.md#cancel-stopping-in-one-write).
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence"]

html_theme = "sphinx_rtd_theme"  # the theme docs.ros.org's rosdoc2 pages use
html_title = "tactile_sensor"

# Tables wrap to the page's width instead of scrolling (docs/_static/tables.css).
html_static_path = ["_static"]
html_css_files = ["tables.css"]
