"""The depth-pilot node's statuses (diagnostic_msgs/DiagnosticStatus), built from the pilot.

The node (:mod:`auv_depth_lqr.node`) publishes three statuses; their fields are listed in its
module docstring:

* ``<node>: depth control`` on ``/diagnostics`` (:func:`control_status`): the pilot's mode,
  its depth command and envelope, the pitch envelope, a depth runaway, what it learned, the
  last command's answer; OK, WARN (recovery, no state yet, a refused or lost command, the
  pitch envelope holding) or ERROR (stale state, a depth runaway:
  :mod:`auv_depth_lqr.runaway`);
* ``<node>: plane authority`` on ``/diagnostics`` (:func:`authority_status`): how much of
  the plane holding depth takes (:mod:`auv_depth_lqr.authority`); WARN when little is left;
* ``<node>: depth command`` on ``depth_command_answer`` (:func:`answer_status`): the answer
  to one depth command; OK accepted, WARN clamped or refused.

Angles in the values are degrees, depths metres (NED, down), rates m/s, as their keys say.
"""
from __future__ import annotations

import math

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from auv_depth_lqr.authority import LOW
from auv_depth_lqr.command_intake import ACCEPTED, CommandAnswer
from auv_depth_lqr.pilot import DepthPilot

__all__ = ['LEVELS', 'answer_status', 'answer_values', 'authority_status', 'authority_text',
           'control_status', 'status_text']

LEVELS = {'ok': DiagnosticStatus.OK, 'recovery': DiagnosticStatus.WARN,
          'no_state': DiagnosticStatus.WARN, 'stale': DiagnosticStatus.ERROR}
"""Level of the depth-control status per :attr:`DepthPilot.status` (ERROR otherwise)."""


def _status(level: int, name: str, message: str, hardware_id: str,
            values: dict[str, str]) -> DiagnosticStatus:
    out = DiagnosticStatus()
    out.level, out.name, out.message, out.hardware_id = level, name, message, hardware_id
    out.values = [KeyValue(key=k, value=v) for k, v in values.items()]
    return out


def status_text(pilot: DepthPilot, status: str) -> str:
    """One line saying the pilot's ``status`` (``ok``, ``recovery``, ``stale``,
    ``no_state``): also the node's log line when the status changes."""
    if status == 'ok':
        verdict = pilot.verdict
        if verdict is not None and verdict.changed and verdict.mode == 'normal':
            return verdict.reason
        return 'state received: depth control active'
    if status == 'recovery':
        reason = pilot.verdict.reason if pilot.verdict else ''
        return f'envelope left ({reason}): recovery law, levelling the vehicle'
    if status == 'stale':
        return (f'no state for more than {pilot.settings.state_timeout} s: publishing safe '
                f'BAR {pilot.settings.safe_bar:.3f} rad')
    if status == 'no_state':
        return 'no state yet: publishing safe BAR'
    return status


def authority_text(pilot: DepthPilot) -> str:
    """One line on the plane authority (:meth:`auv_depth_lqr.authority.Authority.message`)."""
    monitor = pilot.authority_monitor
    return pilot.authority.message(monitor.share_max, monitor.saturated_max)


def authority_status(pilot: DepthPilot, node_name: str, hardware_id: str
                     ) -> DiagnosticStatus:
    """The plane authority as a status named ``<node_name>: plane authority``: WARN when
    low."""
    a, monitor = pilot.authority, pilot.authority_monitor

    def number(value: float, scale: float = 1.0, digits: int = 2) -> str:
        return f'{value * scale:.{digits}f}' if math.isfinite(value) else 'none'

    values = {
        'level': a.level,
        'hold_bar_deg': number(a.hold_bar, 180.0 / math.pi),
        'hold_share_of_travel': number(a.share, digits=3),
        'hold_share_at_stop': number(a.saturated, digits=3),
        'hold_time_s': number(a.hold_time, digits=1),
        'window_share_at_stop': number(a.at_stop, digits=3),
        'window_s': number(monitor.window, digits=1),
        'bar_max_deg': number(monitor.bar_max, 180.0 / math.pi),
    }
    return _status(DiagnosticStatus.WARN if a.level == LOW else DiagnosticStatus.OK,
                   f'{node_name}: plane authority', authority_text(pilot), hardware_id, values)


def answer_values(answer: CommandAnswer) -> dict[str, str]:
    """The answer's fields as diagnostic key/values."""
    return {'value_m': f'{answer.value:g}', 'result': answer.result,
            'depth_m': 'none' if answer.depth is None else f'{answer.depth:g}',
            'reason': answer.reason, 'publisher': answer.publisher,
            'sequence': str(answer.sequence)}


def answer_status(answer: CommandAnswer, node_name: str, hardware_id: str
                  ) -> DiagnosticStatus:
    """The answer to a depth command as a status named ``<node_name>: depth command``: OK
    accepted, WARN clamped or refused."""
    level = DiagnosticStatus.OK if answer.result == ACCEPTED else DiagnosticStatus.WARN
    return _status(level, f'{node_name}: depth command', answer.text(), hardware_id,
                   answer_values(answer))


def control_status(pilot: DepthPilot, node_name: str, hardware_id: str, t_command: float,
                   command_warning: str, last_refusal: str,
                   last_answer: CommandAnswer | None) -> DiagnosticStatus:
    """The depth control as a status named ``<node_name>: depth control``.

    Parameters
    ----------
    pilot : DepthPilot
        The pilot, after its last command.
    node_name, hardware_id : str
        The node's fully qualified name and its namespace.
    t_command : float
        Time of the last command [s] (for the pitch envelope's warning).
    command_warning : str
        A refused or lost depth command ('' none): WARN, appended to the message.
    last_refusal : str
        The last command refused ('' none).
    last_answer : CommandAnswer or None
        The answer to the last depth command (its fields as ``last_command_*``).
    """
    status, verdict = pilot.status, pilot.verdict
    level = LEVELS.get(status, DiagnosticStatus.ERROR)
    message = status_text(pilot, status)
    envelope = pilot.envelope_warning(t_command)
    for warning in (command_warning, envelope):
        if warning:
            level = max(level, DiagnosticStatus.WARN)
            message = f'{message}; {warning}'
    runaway = pilot.runaway_monitor.state
    if runaway is not None:
        level = DiagnosticStatus.ERROR
        message = f'{message}; {pilot.runaway_warning()}'
    values = {
        'status': status,
        'mode': verdict.mode if verdict else 'normal',
        'reason': verdict.reason if verdict else '',
        'depth_command_m': 'none' if pilot.z_ref is None else f'{pilot.z_ref:.3f}',
        'depth_min_m': f'{pilot.depth_min:g}', 'depth_max_m': f'{pilot.depth_max:g}',
        'last_rejected_command': last_refusal,
        'pitch_deg': 'none' if verdict is None else f'{math.degrees(verdict.pitch):.2f}',
        'pitch_limit_deg': f'{math.degrees(pilot.controller.limits.theta_max):g}',
        'pitch_envelope': pilot.envelope_state(t_command),
        'depth_runaway_m': ('none' if runaway is None else
                            f'{runaway.off:.2f} {"below" if runaway.below else "above"}'),
        'depth_rate_residual_mps': ('none' if verdict is None or verdict.residual is None
                                    else f'{verdict.residual:+.3f}'),
        **pilot.speed_diagnostics(),
        **pilot.learning_diagnostics(),
    }
    if last_answer is not None:
        values.update({f'last_command_{k}': v for k, v in answer_values(last_answer).items()})
    return _status(level, f'{node_name}: depth control', message, hardware_id, values)
