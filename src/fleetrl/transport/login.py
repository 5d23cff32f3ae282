"""The broker password, kept off command lines and out of files a run writes: the URL names the user, the
password comes from a 0600 file (``--broker-password-file``) or ``FLEETRL_BROKER_PASSWORD``."""

from __future__ import annotations

import os
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from urllib.parse import unquote, urlsplit, urlunsplit

PASSWORD_ENV = "FLEETRL_BROKER_PASSWORD"


def password_in_url(url: str) -> bool:
    """Whether ``url`` carries a password (``scheme://user:password@host``)."""
    return urlsplit(url).password is not None


def without_password(url: str) -> str:
    """``url`` without its password (the user stays): safe to log, write and put on a command line."""
    parts = urlsplit(url)
    if parts.password is None:
        return url
    host = parts.hostname or ""
    if ":" in host:  # an IPv6 literal
        host = f"[{host}]"
    netloc = f"{parts.username}@{host}" if parts.username else host
    if parts.port is not None:
        netloc += f":{parts.port}"
    return urlunsplit((parts.scheme, netloc, parts.path, parts.query, parts.fragment))


def read_password_file(path: Path) -> str:
    """The password in ``path`` (its first line); ValueError if the file holds none."""
    lines = path.read_text().splitlines()
    if not lines or not lines[0].strip():
        raise ValueError(f"{path} holds no password")
    return lines[0].strip()


def broker_password(
    password_file: Path | None, url: str | None = None, environ: Mapping[str, str] | None = None
) -> str | None:
    """The broker password: from ``password_file``, else inside ``url``, else ``FLEETRL_BROKER_PASSWORD``
    (from ``environ``, default this process's environment); None if there is none."""
    if password_file is not None:
        return read_password_file(password_file)
    if url is not None and (inside := urlsplit(url).password) is not None:
        return unquote(inside)
    value = (os.environ if environ is None else environ).get(PASSWORD_ENV)
    return value or None


@contextmanager
def password_in_environment(password: str | None) -> Iterator[None]:
    """``password`` in ``FLEETRL_BROKER_PASSWORD`` while the block runs (None: nothing changes), for every
    transport of this process and its children."""
    if password is None:
        yield
        return
    saved = os.environ.get(PASSWORD_ENV)
    os.environ[PASSWORD_ENV] = password
    try:
        yield
    finally:
        if saved is None:
            os.environ.pop(PASSWORD_ENV, None)
        else:
            os.environ[PASSWORD_ENV] = saved
