"""The static comparison site (DESIGN.md §18): ``prtbench report``.

:mod:`.data` reads what the pages show from the results store and the cache, :mod:`.panels`
lays a scene page out in the ranking protocol's panels (docs/PROTOCOL.md), :mod:`.images`
makes (once, cached) the PNGs, :mod:`.plot` the Pareto plots and :mod:`.build` renders the
Jinja2 templates (``templates/``) with the scripts and styles of ``static/`` into a folder
that opens from the file system, offline.
"""
