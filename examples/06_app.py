"""The browser app from Python: any cloud, a viser server, the same app as `serve`.

    python examples/06_app.py            # open the printed URL; Ctrl-C to stop
    python examples/06_app.py --check    # build, compute the first map, stop

Everything the GUI shows is also on the returned App object. ``open_server`` puts
the same Origin check and access token in front of viser as ``serve`` does; the
printed URL carries the token.
"""

from __future__ import annotations

import sys

import rough_viewer as rv
from rough_viewer.app.gate import new_token, open_server
from rough_viewer.app.server import build_app

cloud = rv.load_demo("outcrop-small")
server, gate = open_server("127.0.0.1", 0 if "--check" in sys.argv else 8080,
                           token=new_token())
app = build_app(server, cloud)
app.wait_idle(120)
shown = app.session.shown
print(f"showing {shown.loaded.n_display:,} of {cloud.n:,} points, "
      f"grid {shown.settings.cell_size:g} m, model {shown.settings.model}")
if "--check" not in sys.argv:
    print(f"open {gate.url('127.0.0.1', server.get_port())}")
    try:
        while True:
            server.sleep_forever()
    except KeyboardInterrupt:
        pass
app.stop()
server.stop()
