"""usdmotion studio: a local web app to browse, play and compare takes.

``library`` finds takes under the given roots (and nothing outside them), ``takes``
turns one take into what the browser draws (joint positions, analysis series, compare
alignment, GLB), ``app`` is the ASGI app over both, ``web/`` the front end (plain ES
modules, three.js and uPlot from the local ``node_modules`` through an import map).
"""
