"""Who may read the live page: the person who started it (issue 26 §5).

Binding to 127.0.0.1 keeps other machines out, but not the web pages the person's own
browser shows: any of them may open a websocket to ``ws://127.0.0.1:8765/`` (browsers do
not apply the same-origin policy to websockets) or, through DNS rebinding, fetch from a
name that resolves to 127.0.0.1. So, as Jupyter does, every request must

- name this server in its ``Host`` header (``127.0.0.1:PORT`` or ``localhost:PORT``), which a
  rebound name does not;
- come from this server's own pages when it says where it comes from (``Origin``), which a
  browser always does for a websocket and for a cross-origin fetch;
- carry the session's token (``?token=``, or an ``Authorization: token ...`` header), which
  only the address the command printed holds; compared in constant time.

The page's own files (``/static/``: the same for everyone, no data) need no token, nor does
``/favicon.ico``, which a browser asks for without the page's query (answered 204, empty).
"""

from __future__ import annotations

import hmac
import secrets
from collections.abc import Mapping

__all__ = ["PUBLIC_PATHS", "AccessPolicy", "new_token"]

#: Paths answered without the token (still only to this Host and Origin): they carry no
#: data. A browser asks for ``/favicon.ico`` on its own, without the page's ``?token=``.
PUBLIC_PATHS = frozenset({"/favicon.ico"})


def new_token() -> str:
    """A fresh session token: 32 random bytes, URL-safe."""
    return secrets.token_urlsafe(32)


class AccessPolicy:
    """The checks of one server on ``host:port`` with ``token``.

    Parameters
    ----------
    host : str
        The address the server listens on.
    port : int
        Its port (once bound: ``0`` is not a port a browser names).
    token : str
        The session's token.
    """

    def __init__(self, host: str, port: int, token: str) -> None:
        names = {host, "127.0.0.1", "localhost"} if host in ("127.0.0.1", "localhost") \
            else {host}
        self.hosts = frozenset(f"{name}:{port}" for name in names)
        self.origins = frozenset(f"http://{name}" for name in self.hosts)
        self._token = token.encode("utf-8")

    def host_error(self, headers: Mapping[str, str]) -> str | None:
        """Why the ``Host`` header is refused, or None."""
        host = headers.get("Host")
        if host is None:
            return "the request names no Host"
        if host.lower() not in self.hosts:
            return f"Host {host!r} is not this server ({', '.join(sorted(self.hosts))})"
        return None

    def origin_error(self, headers: Mapping[str, str]) -> str | None:
        """Why the ``Origin`` header is refused (a page of another site), or None (none
        given, as from a script, or this server's own page)."""
        origin = headers.get("Origin")
        if origin is None or origin.lower() in self.origins:
            return None
        return f"a page from {origin!r} may not read this server"

    def token_error(self, query: Mapping[str, str], headers: Mapping[str, str]) -> str | None:
        """Why the request's token is refused, or None when it is the session's."""
        given = query.get("token")
        if given is None:
            scheme, _, value = headers.get("Authorization", "").partition(" ")
            given = value.strip() if scheme.lower() == "token" else None
        if not given:
            return ("this page needs its token: open the address the command printed "
                    "(http://...:PORT/?token=...)")
        if not hmac.compare_digest(given.encode("utf-8", "surrogateescape"), self._token):
            return "wrong token: open the address the command printed"
        return None

    def refusal(self, path: str, query: Mapping[str, str],
                headers: Mapping[str, str]) -> str | None:
        """Why a request for ``path`` is refused, or None when it may be answered."""
        error = self.host_error(headers) or self.origin_error(headers)
        if error is None and not path.startswith("/static/") and path not in PUBLIC_PATHS:
            error = self.token_error(query, headers)
        return error
