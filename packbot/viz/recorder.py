"""A meshcat window recording commands into a scene tree, for pages that need no server."""

from __future__ import annotations

from typing import Any

import umsgpack
from meshcat.servers.tree import SceneTree, find_node, walk

from packbot.errors import ConfigurationError
from packbot.keywords import checked_arguments

__all__ = ["SceneRecorder"]


@checked_arguments
class SceneRecorder:
    """A meshcat window that records commands into a scene tree instead of sending them.

    Plug it into ``meshcat.Visualizer(window=SceneRecorder())``. Every command replaces or
    extends the state of its node exactly as meshcat's server does (``set_object`` resets the
    node's properties, ``delete`` drops the subtree), so :meth:`commands` replays the final
    scene. Floats are packed in single precision (the viewer uses 32-bit floats anyway).

    Attributes:
        tree: meshcat's ``SceneTree`` of packed commands.
        web_url: Empty: nothing is served.
    """

    web_url = ""

    def __init__(self) -> None:
        self.tree = SceneTree()

    def send(self, command: Any) -> None:
        """Record one meshcat command (``SetObject``, ``SetTransform``, ...)."""
        data = command.lower()
        kind = data["type"]
        packed = umsgpack.packb(data, force_float_precision="single")
        path = [p for p in str(data.get("path", "")).split("/") if p]
        node = find_node(self.tree, path)
        if kind == "set_object":
            node.object = packed
            node.properties = []
        elif kind == "set_transform":
            node.transform = packed
        elif kind == "set_property":
            node.properties.append(packed)
        elif kind == "set_animation":
            node.animation = packed
        elif kind == "delete":
            if path:
                parent = find_node(self.tree, path[:-1])
                parent.pop(path[-1], None)
            else:
                self.tree = SceneTree()
        else:
            raise ConfigurationError("meshcat command", kind, "a scene command")

    def commands(self) -> list[bytes]:
        """The packed commands that rebuild the scene: objects first, animations last."""
        out: list[bytes] = []
        animations: list[bytes] = []
        for node in walk(self.tree):
            if node.object is not None:
                out.append(node.object)
            out.extend(node.properties)
            if node.transform is not None:
                out.append(node.transform)
            if node.animation is not None:
                animations.append(node.animation)
        return out + animations

    def open(self) -> SceneRecorder:
        """Nothing to open (meshcat's window interface)."""
        return self
