"""drivestudio studio: a live studio in the browser (docs/studio.md).

    server.py     the web server (aiohttp) in its own thread: the page, its static files, one WebSocket per page
    protocol.py   the WebSocket messages: what a page may send, checked; the frame message the server sends
    session.py    the studio's run: world, driver (the person included), supervisor, metrics, recording, resets
    human.py      the person at the controls: keyboard ramps, gamepad axes
    kit.py        what a world gives the studio (its view, scenes, human command map): each world's studio.py
    watch.py      a run's steps as the pages see them (the studio's and a watched job's)
    publisher.py  the newest step, taken at the pages' pace, encoded off the loop's thread
    controls.py   pause, single step and pace, obeyed by the loop's thread
    recording.py  what is driven, recorded as a dataset of the project's format
    view.py       drive --view and serve --view
    static/       the page: index.html, studio.js, studio.css (no build step, nothing fetched elsewhere)
"""
