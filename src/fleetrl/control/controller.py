"""``fleetrl control``: a saved policy run greedily on one unit, at its control period, through its driver.

The unit is served by the device bridge itself (``fleetrl.link.bridge.DeviceBridge``, the code ``fleetrl
device`` runs), in this process, over the in-process bus; the unit's env reaches it through the same link a
worker uses (``MqttLink``), so the policy acts on exactly what a worker's agent would see. The unit thus
keeps every safety of the bridge, in the same code:

* the watchdog: no command for ``watchdog`` seconds (a stalled policy) switches the motor off;
* the protective stop: the arm past its limit switches the motor off and refuses steps until a reset;
* any driver fault (the QUBE's ``QubeFault``: a wrong device id, a stuck encoder, a dead bus) ends the run
  with the amplifier disabled and the fault's own message;
* Ctrl-C or SIGTERM, or any error, stops the bridge: motor off, driver closed.

In lockstep (a simulated unit, default) each step holds its command for one period of simulated time,
exactly as an in-process step does: the scores are ``fleetrl evaluate``'s. In real time (``--realtime``,
always on hardware) the bridge ticks every control period on the driver's clock, the rig's answer-before-
acting order (one period of actuation delay, as the simulator models it).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from fleetrl.control.episodes import greedy_scores
from fleetrl.control.export import check_fits
from fleetrl.control.policies import GreedyPolicy
from fleetrl.envs.catalog import describe_env, get_env_spec
from fleetrl.envs.device_side import check_driver_fits, check_takes_link
from fleetrl.link.bridge import WATCHDOG_SECONDS, DeviceBridge
from fleetrl.link.driver import DeviceDriver
from fleetrl.link.mqtt import DeviceLinkError, MqttLink
from fleetrl.transport.local import LocalBus

log = logging.getLogger(__name__)

RUN_ID = "control"
"""the run id of the in-process bus's device topics"""
JOIN_SECONDS = 5.0
"""how long closing waits for the bridge's thread to switch the motor off and return"""


class _ServedUnit:
    """The bridge serving the driver in a thread; whatever ends it (a fault included) closes it at once:
    motor off, ``offline`` announced (so the link stops waiting), driver closed."""

    def __init__(self, bridge: DeviceBridge) -> None:
        self.bridge = bridge
        self.error: BaseException | None = None
        """what ended the bridge's loop, if not a stop request"""
        bridge.open()
        name = f"fleetrl-control-{bridge.unit}"
        self._thread = threading.Thread(target=self._serve, name=name, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        try:
            self.bridge.serve()  # its finally switches the motor off
        except BaseException as err:
            self.error = err
            log.error("unit %d: the bridge stopped on a fault: %s", self.bridge.unit, err)
        finally:
            self.bridge.close()

    def close(self) -> None:
        """Stop the bridge and wait for it to have switched the motor off and closed the driver."""
        self.bridge.stop()
        self._thread.join(JOIN_SECONDS)
        if self._thread.is_alive():
            log.error("unit %d: the bridge did not stop within %.0f s", self.bridge.unit, JOIN_SECONDS)


def run_on_unit(
    policy: GreedyPolicy,
    env: str,
    driver: DeviceDriver,
    episodes: int,
    *,
    seed: int = 0,
    unit: int = 0,
    fleet_seed: int = 0,
    realtime: bool = False,
    watchdog: float = WATCHDOG_SECONDS,
    report: Callable[[int, float], None] | None = None,
) -> list[float]:
    """The scores of ``episodes`` greedy episodes of ``policy`` on the unit ``driver`` drives, judged by
    ``env``'s reward (episode ``k`` resets with seed ``seed + k``; ``report(k, score)`` as each ends). The
    driver is closed (motor off) when this returns or raises.

    :raises ValueError: the policy or the driver does not fit ``env`` (nothing has moved)
    :raises OSError: the unit failed (a driver fault, a refused step or reset): the motor is off
    """
    try:
        if episodes < 1:
            raise ValueError(f"--episodes must be at least 1, got {episodes}")
        spec = get_env_spec(env)
        check_takes_link(spec)
        description = describe_env(env)
        check_fits(policy.obs_dim, policy.action_space, description, env)
        check_driver_fits(driver.spec, description, f"driver {driver.spec.kind!r}")
        bus = LocalBus()
        bridge = DeviceBridge(bus.client(), driver, RUN_ID, unit, realtime=realtime, watchdog=watchdog)
    except BaseException:
        driver.close()
        raise
    served = _ServedUnit(bridge)
    try:
        link = MqttLink(bus.client(), RUN_ID, unit, obs_size=description.sensor_dim)
        gym_env, _ = spec.make(unit, fleet_seed, link=link)
        try:
            return greedy_scores(gym_env, policy.act, episodes, seed, report)
        finally:
            gym_env.close()
    except DeviceLinkError:
        if served.error is not None:  # the bridge went offline because the driver failed: say why
            raise served.error from None
        raise
    finally:
        served.close()
