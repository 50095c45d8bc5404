"""Browser visualisation with meshcat: self-contained HTML animations and a live viewer.

Both draw the same scene through Pinocchio's ``MeshcatVisualizer``: the robot's visual geometry
(the URDF's STL meshes and colours) and its convex collision pieces (hidden unless asked for;
every node can be toggled in the page's "Scene" panel), the environment (the floor as a slab
under ``z = 0``, boxes, convex obstacles) and, while a contact is active (from its ``impact`` to
its ``release`` in the result's event log), a red marker at the pair's witness points and the
touching pieces turned red. A result plays as one meshcat animation clip: keyframes every
1/:data:`FPS` s of simulated time plus the event instants, scaled by ``speed`` (1 = real time).

- :func:`write_html` writes a page that needs no server and no network: meshcat's bundled
  viewer (three.js) is inlined, the scene and the clip are embedded as the viewer's own msgpack
  commands, recorded in-process by :class:`SceneRecorder` (meshcat 0.3.2's
  ``Visualizer.static_html()`` would ask a running server for them). Open it with
  ``file://...``: it plays the run from its start, with play/pause, speed, a time slider and
  the list of events to jump to, the camera fitted to the motion; a fragment ``#t=0.4`` shows
  the pose at 0.4 s of simulated time, paused.
- :func:`start_viewer` serves the live viewer on 127.0.0.1 only (meshcat's bridge binds its
  web server to every interface whatever its ``host``; ours passes the loopback address to
  tornado) and returns a :class:`LiveViewer`.

Modules: :mod:`~packbot.viz.scene` (what is drawn and the animation clip),
:mod:`~packbot.viz.keyframes` (when the clip samples a result), :mod:`~packbot.viz.contacts`
(contact spans of the event log), :mod:`~packbot.viz.recorder` (the recording meshcat window),
:mod:`~packbot.viz.html` (the offline page) and :mod:`~packbot.viz.live` (the live viewer).
"""

from packbot.viz.contacts import ContactSpan, contact_spans
from packbot.viz.html import html_page, write_html
from packbot.viz.keyframes import FPS
from packbot.viz.live import LOOPBACK, LiveViewer, start_viewer
from packbot.viz.recorder import SceneRecorder
from packbot.viz.scene import CONTACT_COLOR

__all__ = [
    "CONTACT_COLOR",
    "FPS",
    "LOOPBACK",
    "ContactSpan",
    "LiveViewer",
    "SceneRecorder",
    "contact_spans",
    "html_page",
    "start_viewer",
    "write_html",
]
