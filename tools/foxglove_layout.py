"""Write the Foxglove layout of the node graph: ``config/foxglove/auv_graph_layout.json``.

Built with the Foxglove SDK's layout classes (``foxglove.layouts``, the package the bridge
already uses), so the file follows the app's layout format. Panels, for ``auv launch
--foxglove`` (live) or a recorded bag opened in the app:

* 3D: the vehicle's pose and hull (``/auv/pose``, ``/auv/tf``, ``/auv/hull``; ENU/FLU),
  following ``base_link``;
* depth: ``/auv/state.z`` [m, NED, positive down] against ``/auv/depth_command.data`` [m];
* pitch and plane: ``/auv/state.theta`` [rad] and ``/auv/bar_command.value`` [rad];
* the pilot's ``/diagnostics`` (depth control, plane authority, the last depth command's answer).

Run: ``python tools/foxglove_layout.py [OUT]``; ``tests/test_foxglove.py`` checks that
the file in the repository is what this writes.
"""
from __future__ import annotations

import json
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
OUT = ROOT / 'config' / 'foxglove' / 'auv_graph_layout.json'


def layout_json() -> str:
    """The layout as indented JSON text (stable: the same text on every run)."""
    import foxglove.layouts as fl

    def plot(title: str, series: list[tuple[str, str, str]], y_label: str) -> fl.PlotPanel:
        return fl.PlotPanel(title=title, config=fl.PlotConfig(
            paths=[fl.PlotSeries(value=path, label=label, timestamp_method=stamp)
                   for path, label, stamp in series],
            y_axis_label=y_label, show_legend=True, legend_display='floating',
            time_window_mode='sliding', following_view_width=60.0))

    three_d = fl.ThreeDeePanel(title='vehicle (ENU/FLU)', config=fl.ThreeDeeConfig(
        follow_tf='base_link', follow_mode='follow-pose',
        topics={'/auv/pose': fl.BaseRendererPoseTopicSettings(visible=True, type='arrow'),
                '/auv/hull': fl.BaseRendererSceneUpdateTopicSettings(visible=True)},
        camera_state=fl.ThreeDeeCameraState(distance=15.0, perspective=True, phi=60.0,
                                            theta_offset=45.0)))
    depth = plot('depth [m, positive down]',
                 [('/auv/state.z', 'depth z', 'headerStamp'),
                  ('/auv/depth_command.data', 'command', 'receiveTime')], 'm')
    pitch = plot('pitch and dive plane [rad]',
                 [('/auv/state.theta', 'pitch theta', 'headerStamp'),
                  ('/auv/bar_command.value', 'BAR', 'headerStamp')], 'rad')
    diagnostics = fl.DiagnosticsSummaryPanel(
        title='pilot diagnostics',
        config=fl.DiagnosticsSummaryConfig(topic_to_render='/diagnostics', sort_by_level=True))
    layout = fl.Layout(content=fl.SplitContainer(direction='row', items=[
        fl.SplitItem(proportion=1, content=three_d),
        fl.SplitItem(proportion=1, content=fl.SplitContainer(direction='column', items=[
            fl.SplitItem(proportion=1, content=depth),
            fl.SplitItem(proportion=1, content=pitch),
            fl.SplitItem(proportion=1, content=diagnostics),
        ])),
    ]))
    return json.dumps(json.loads(layout.to_json()), indent=2, sort_keys=True) + '\n'


def main() -> None:
    out = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else OUT
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(layout_json())
    print(out)


if __name__ == '__main__':
    main()
