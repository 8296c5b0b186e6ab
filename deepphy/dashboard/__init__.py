"""`deepphy dashboard`: a live web view of run directories and of the runs on a Ray cluster.

source.py  one run directory: the log tailed by byte offset, the report, grid and episodes
live.py    runs found on a Ray cluster by their named metrics actors
server.py  aiohttp: the page, a JSON API and Server-Sent Events
static/    the page (plain HTML, CSS and JavaScript; charts in inline SVG)
"""
