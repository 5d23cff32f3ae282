"""Issue 14 (4): a broker password never reaches a command line (ps), a run directory or a log."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from cli_helpers import Fleetrl

from fleetrl.runs.secure import find_mosquitto_passwd
from fleetrl.transport.broker import EmbeddedBroker, free_port

pytestmark = [
    pytest.mark.mqtt,
    pytest.mark.mosquitto,
]
PASSWORD = "s3cret-Pa55word"


def everything_written(out: Path) -> str:
    """Every text file under ``out`` (config, logs, summaries), concatenated."""
    texts = []
    for path in out.rglob("*"):
        if path.is_file() and path.suffix in (".json", ".toml", ".log", ".csv", ""):
            texts.append(path.read_text(errors="replace"))
    return "\n".join(texts)


def test_secure_config_prints_no_password_and_writes_password_files(fleetrl: Fleetrl) -> None:
    with tempfile.TemporaryDirectory(prefix="fleetrl-secrets-") as name:
        done = fleetrl("secure-config", name, "--workers", "2", "--no-tls", "--port", str(free_port()))
        assert done.returncode == 0, done.stderr
        files = {user: Path(name) / "passwords" / user for user in ("chief", "0", "1")}
        passwords = {user: f.read_text().strip() for user, f in files.items()}
        assert all(len(p) >= 16 for p in passwords.values())
        assert all(f.stat().st_mode & 0o777 == 0o600 for f in files.values())
        credentials = (Path(name) / "credentials.json").read_text()
        for user, password in passwords.items():
            assert password not in done.stdout and password not in credentials
            assert f"--broker-password-file {files[user]}" in done.stdout
        assert "--broker 'mqtt://chief@127.0.0.1:" in done.stdout


@pytest.fixture(scope="module")
def login_broker() -> Iterator[str]:
    """A mosquitto that lets in user ``fleet`` with :data:`PASSWORD` only; yields its URL (no password)."""
    with tempfile.TemporaryDirectory(prefix="fleetrl-login-") as name:
        os.chmod(name, 0o755)  # mosquitto started as root drops to its own user
        passwd, port = Path(name) / "passwd", free_port()
        subprocess.run([find_mosquitto_passwd(), "-c", "-b", str(passwd), "fleet", PASSWORD], check=True)
        passwd.chmod(0o644)
        config = Path(name) / "mosquitto.conf"
        config.write_text(f"listener {port} 127.0.0.1\nallow_anonymous false\npassword_file {passwd}\n")
        config.chmod(0o644)
        with EmbeddedBroker("mosquitto", port=port, config=config):
            yield f"mqtt://fleet@127.0.0.1:{port}"


class ArgvWatcher:
    """Collects the command line of every process on the machine while a run goes on."""

    def __init__(self) -> None:
        self.seen: set[str] = set()
        self.running = True
        self.thread = threading.Thread(target=self._watch, daemon=True)
        self.thread.start()

    def _watch(self) -> None:
        while self.running:
            for proc in Path("/proc").glob("[0-9]*"):
                try:
                    argv = (proc / "cmdline").read_bytes()
                    self.seen.add(argv.replace(b"\0", b" ").decode(errors="replace"))
                except OSError:
                    continue
            time.sleep(0.2)

    def stop(self) -> set[str]:
        self.running = False
        self.thread.join(5)
        return self.seen


@pytest.mark.slow
@pytest.mark.timeout(240)
@pytest.mark.parametrize("how", ["password-file", "environment", "in-the-url"])
def test_a_run_logs_in_without_the_password_in_any_argv_or_file(
    tmp_path: Path, login_broker: str, how: str
) -> None:
    out = tmp_path / "run"
    # worker processes as new interpreters, whose command lines fleetrl writes (a forked worker's is the
    # launcher's own, the user's command line)
    url, extra, env = login_broker, [], dict(os.environ, FLEETRL_WORKER_START="spawn")
    if how == "password-file":
        secret = tmp_path / "broker.pw"
        secret.write_text(PASSWORD + "\n")
        extra = ["--broker-password-file", str(secret)]
    elif how == "environment":
        env["FLEETRL_BROKER_PASSWORD"] = PASSWORD
    else:
        url = login_broker.replace("fleet@", f"fleet:{PASSWORD}@")
    # the paper's scheme, one exchange per round: the login is tested here, not the scheme
    argv = ["train", "--env", "cartpole", "--preset", "standard", "--units", "2", "--max-rounds", "3",
            "--scheme", "paper"]  # fmt: skip
    watcher = ArgvWatcher()
    done = subprocess.run(
        [sys.executable, "-m", "fleetrl.cli.main", *argv, "--broker", url, *extra, "--no-live",
         "--out", str(out)],
        capture_output=True, text=True, timeout=200, env=env,
    )  # fmt: skip
    seen = watcher.stop()
    assert done.returncode == 0, done.stderr
    assert json.loads((out / "summary.json").read_text())["rounds"] == 3
    workers = [cmd for cmd in seen if "fleetrl.runs.worker_main" in cmd]
    assert len(workers) >= 2, "the watcher did not see the worker processes"
    leaks = [cmd for cmd in seen if PASSWORD in cmd and "fleetrl.cli.main" not in cmd]
    assert not leaks, leaks  # the user's own command line is theirs; nothing fleetrl starts carries it
    assert PASSWORD not in everything_written(out)
    warned = "the broker URL carries a password" in done.stderr
    assert warned == (how == "in-the-url")
