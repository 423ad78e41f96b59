"""Who may look and who may act on the operator station: tokens, roles, CSRF, the bind policy.

Roles: ``viewer`` may look, ``operator`` may also act (start, abort, pause, resume, confirm,
reject). A token is sent as ``Authorization: Bearer TOKEN`` or as the ``seamguide_token`` cookie
(set by the login form) and compared in constant time (:func:`hmac.compare_digest`). On the
loopback address without a token file everyone who can reach the port is an operator, like the
owner of the control socket; any other bind address needs a token file (refused otherwise). Actions
are POST requests that carry a CSRF token derived from a per-process secret and the caller's
credential (synchroniser token pattern), so another site cannot make an operator's browser act.
"""

from __future__ import annotations

import hashlib
import hmac
import ipaddress
import os
import secrets
import stat
import tomllib
from dataclasses import dataclass
from pathlib import Path

from controller.errors import ConfigError

COOKIE = "seamguide_token"
ROLES = ("viewer", "operator")


@dataclass(frozen=True)
class Tokens:
    """The two role tokens (either may be None: that role cannot log in)."""

    viewer: str | None = None
    operator: str | None = None


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and ``localhost``."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def load_tokens(path: str | os.PathLike[str]) -> Tokens:
    """Read a token file (TOML: ``viewer = "..."``, ``operator = "..."``), owner-only.

    Raises :class:`ConfigError` naming the file when it is missing, readable by others, not TOML,
    or a token is shorter than 16 characters.
    """
    p = Path(path)
    try:
        mode = p.stat().st_mode
        raw = tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError as err:
        raise ConfigError(f"http.token_file {p} does not exist; create it (chmod 600) with "
                          f"viewer = \"...\" and operator = \"...\"", file=str(p)) from err
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"http.token_file {p} is not valid TOML: {err}", file=str(p)) from err
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise ConfigError(f"http.token_file {p} is readable by other users; chmod 600 it",
                          file=str(p))
    out: dict[str, str | None] = {}
    for role in ROLES:
        tok = raw.get(role)
        if tok is not None and (not isinstance(tok, str) or len(tok) < 16):
            raise ConfigError(f"http.token_file {p}: {role} must be a string of at least 16 "
                              f"characters (e.g. from `python -c 'import secrets; "
                              f"print(secrets.token_urlsafe())'`)", file=str(p), key=role)
        out[role] = tok
    unknown = sorted(set(raw) - set(ROLES))
    if unknown:
        raise ConfigError(f"http.token_file {p}: unknown keys {unknown}; use viewer, operator",
                          file=str(p))
    return Tokens(viewer=out["viewer"], operator=out["operator"])


def check_bind(bind: str, tokens: Tokens | None) -> None:
    """Refuse a non-loopback bind without an operator and a viewer token (:class:`ConfigError`)."""
    if is_loopback(bind):
        return
    if tokens is None or tokens.operator is None or tokens.viewer is None:
        raise ConfigError(f"http.bind = {bind!r} is reachable from other machines: set "
                          f"http.token_file with a viewer and an operator token, or bind "
                          f"127.0.0.1", key="http.bind")


def _eq(a: str, b: str | None) -> bool:
    return b is not None and hmac.compare_digest(a.encode(), b.encode())


class Access:
    """Decides the role of a request's credential and makes / checks CSRF tokens."""

    def __init__(self, tokens: Tokens | None) -> None:
        self.tokens = tokens
        self._secret = secrets.token_bytes(32)

    @property
    def open(self) -> bool:
        """True when no token file is configured (loopback only): everyone is an operator."""
        return self.tokens is None

    def role(self, credential: str | None) -> str | None:
        """``operator``, ``viewer`` or None (not allowed to look)."""
        if self.tokens is None:
            return "operator"
        if credential is None:
            return None
        # Both comparisons always run: the time does not tell which token was close.
        op = _eq(credential, self.tokens.operator)
        vw = _eq(credential, self.tokens.viewer)
        return "operator" if op else "viewer" if vw else None

    def csrf_token(self, credential: str | None) -> str:
        """The CSRF token of a credential (stable for the process's life)."""
        return hmac.new(self._secret, (credential or "").encode(), hashlib.sha256).hexdigest()

    def csrf_ok(self, credential: str | None, token: str | None) -> bool:
        """Whether ``token`` is the CSRF token of ``credential`` (constant time)."""
        return token is not None and hmac.compare_digest(token, self.csrf_token(credential))
