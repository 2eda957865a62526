"""How the 3D view is looked at: camera modes (free orbit, follow the ego, top-down), layer
toggles (sensors, candidate paths, traffic, labels) and the legend of its colours, as viser GUI
controls over a :class:`~crossroads.viz.viewer.Viewer`.

The camera of a mode is placed by :func:`crossroads.viz.camera.camera_pose`; the viewer applies it
to each tab's camera on every frame it shows while the mode is not ``orbit``.
"""

from __future__ import annotations

from typing import Any

from crossroads.viz.camera import CAMERA_MODES
from crossroads.viz.viewer import (
    ABNORMAL, COLLIDED, COLLISION_SPOT, EGO, KIND_COLOURS, PATH_CHOSEN, PATH_OTHER, SENSOR_COLOURS, TRAIL, Viewer)

LAYERS: dict[str, str] = {"Sensors": "sensors", "Candidate paths": "paths", "Traffic": "traffic",
                          "Labels": "labels"}
def _swatch(colour: tuple[int, int, int], label: str, opacity: float = 1.0) -> str:
    r, g, b = colour
    return (f'<span style="display:inline-block;margin:0 0.8em 0.2em 0;white-space:nowrap">'
            f'<span style="display:inline-block;width:0.9em;height:0.9em;vertical-align:-0.1em;'
            f'margin-right:0.3em;border:1px solid #8888;background:rgba({r},{g},{b},{opacity})"></span>'
            f'{label}</span>')


def legend_html() -> str:
    """The legend of the view's colours (HTML for ``gui.add_html``)."""
    items = [
        _swatch(EGO, "ego"), _swatch(TRAIL, "ego's trail"),
        _swatch(KIND_COLOURS["vehicle"], "vehicle"), _swatch(KIND_COLOURS["cyclist"], "cyclist"),
        _swatch(KIND_COLOURS["pedestrian"], "pedestrian"), _swatch(ABNORMAL, "abnormal (⚠)"),
        _swatch(COLLIDED, "hit by the ego (✖)"), _swatch(KIND_COLOURS["vehicle"], "unseen by any sensor", 0.45),
        _swatch(PATH_CHOSEN, "chosen path"), _swatch(PATH_OTHER, "other candidate paths"),
        _swatch(SENSOR_COLOURS["lidar"], "sensor ranges"), _swatch(COLLISION_SPOT, "where the ego collided"),
    ]
    return f'<div class="crossroads-legend" style="font-size:0.85em;line-height:1.5">{"".join(items)}</div>'


class ViewControls:
    """The "View" folder of a tab: camera mode, layer toggles and the legend, acting on ``viewer``.
    ``gui``: the target's GUI API (``client.gui`` or ``server.gui``)."""

    def __init__(self, gui: Any, viewer: Viewer, *, folder_label: str = "View") -> None:
        self.viewer = viewer
        self.handles: list[Any] = []
        with gui.add_folder(folder_label) as folder:
            self.handles.append(folder)
            self.camera = gui.add_dropdown("Camera", tuple(CAMERA_MODES), initial_value="free orbit")
            self.layers = {key: gui.add_checkbox(label, initial_value=True) for label, key in LAYERS.items()}
            self.legend = gui.add_html(legend_html())
        self.handles += [self.camera, *self.layers.values(), self.legend]

        @self.camera.on_update
        def _(_event: Any) -> None:
            viewer.set_camera_mode(CAMERA_MODES[str(self.camera.value)])

        for key, box in self.layers.items():
            box.on_update(lambda _event, key=key, box=box: viewer.set_layer(key, bool(box.value)))

    def remove(self) -> None:
        for handle in reversed(self.handles):
            try:
                handle.remove()
            except Exception:  # noqa: BLE001 - already gone with its folder or tab
                pass
