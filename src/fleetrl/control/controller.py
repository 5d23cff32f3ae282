"""``fleetrl control``: a saved policy run greedily on one unit, at its control period, through its driver.

The unit is served by the device bridge itself, in this process, and its env reaches it through the link a
worker uses, so the policy sees what a worker's agent would and the unit keeps every safety of the bridge
(docs/on-device.md). The bridge runs in the main thread, so an interrupt stops it; the policy plays in a
second thread.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from fleetrl.control.episodes import greedy_scores
from fleetrl.control.policies import GreedyPolicy, check_fits
from fleetrl.envs.catalog import check_driver_fits, check_takes_link, describe_env, get_env_spec
from fleetrl.link.bridge import WATCHDOG_SECONDS, DeviceBridge
from fleetrl.link.driver import DeviceDriver
from fleetrl.link.mqtt import MqttLink
from fleetrl.transport.local import LocalBus

log = logging.getLogger(__name__)

RUN_ID = "control"  # the run id of the in-process bus's device topics
JOIN_SECONDS = 5.0  # how long the controller waits for the policy's thread once the bridge has closed


class _Episodes:
    """The policy's side, in a thread: the unit's env over a link to the bridge, ``greedy_scores`` on it;
    when the episodes end (or fail) it asks the bridge to stop."""

    def __init__(self, bridge: DeviceBridge, play: Callable[[], list[float]]) -> None:
        self.scores: list[float] = []
        self.error: BaseException | None = None  # what ended the episodes early
        self._bridge, self._play = bridge, play
        self._thread = threading.Thread(target=self._run, name="fleetrl-control-policy", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            self.scores = self._play()
        except BaseException as err:
            self.error = err
        finally:
            self._bridge.stop()

    def join(self) -> None:
        """Wait for the thread (the closed bridge's ``offline`` ends any wait of its link at once)."""
        self._thread.join(JOIN_SECONDS)


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
        check_fits(policy.obs_dim, policy.action_space, describe_env(env, policy.last_step), env)
        check_driver_fits(driver.spec, description, f"driver {driver.spec.kind!r}")
        bus = LocalBus()
        bridge = DeviceBridge(bus.client(), driver, RUN_ID, unit, realtime=realtime, watchdog=watchdog)
    except BaseException:
        driver.close()
        raise

    def play() -> list[float]:
        link = MqttLink(bus.client(), RUN_ID, unit, obs_size=description.sensor_dim)
        gym_env, _ = spec.make(unit, fleet_seed, link=link, last_step=policy.last_step)
        try:
            return greedy_scores(gym_env, policy.act, episodes, seed, report)
        finally:
            gym_env.close()

    # The bridge runs in this (the main) thread, as under `fleetrl device`: Ctrl-C and SIGTERM interrupt it
    # wherever it is — a device-side reset included — and it switches the motor off on the way out.
    try:
        bridge.open()
        played = _Episodes(bridge, play)
        bridge.serve()  # until the episodes end; a driver fault or an interrupt raises here, motor off
    finally:
        bridge.close()  # motor off, offline (which ends the policy's wait), driver closed
    played.join()
    if played.error is not None:
        raise played.error
    return played.scores
