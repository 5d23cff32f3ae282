"""``fleetrl control``: a saved policy run greedily on one unit through its driver, served by a device bridge
in this process (main thread, so an interrupt stops it) and reached through a worker's link by the policy
(a second thread): it sees what a worker's agent would, the unit keeps every safety of the bridge."""

from __future__ import annotations

import threading
from collections.abc import Callable

from fleetrl.control.policies import GreedyPolicy, check_fits, greedy_scores
from fleetrl.envs.catalog import check_takes_link, describe_env, get_env_spec
from fleetrl.envs.device_side import check_driver_fits
from fleetrl.link.bridge import WATCHDOG_SECONDS, DeviceBridge
from fleetrl.link.driver import DeviceDriver
from fleetrl.link.mqtt import MqttLink
from fleetrl.transport.local import LocalBus

RUN_ID = "control"  # the run id of the in-process bus's device topics
JOIN_SECONDS = 5.0  # how long the controller waits for the policy's thread once the bridge has closed


class _Episodes:
    """The policy's side, in a thread; when its episodes end (or fail) it asks the bridge to stop."""

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
    ``env``'s reward (as :func:`greedy_scores`); the driver is closed (motor off) when this returns or raises:
    a ValueError if the policy or the driver does not fit ``env``, an OSError if the unit failed."""
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

    # the bridge runs in the main thread: Ctrl-C and SIGTERM interrupt it anywhere; it turns the motor off
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
