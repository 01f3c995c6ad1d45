# SPDX-License-Identifier: Apache-2.0
"""The meshcat server that h4pin's viewer starts: meshcat's own bridge, bound to one interface.

meshcat 0.3.2's server (``python -m meshcat.servers.zmqserver``) binds its ZeroMQ command socket to
127.0.0.1 but its web server to every interface (tornado's ``listen(port)`` without an address),
and has no option to choose. This module runs the same :class:`ZMQWebSocketBridge` with:

* the web server bound to ``--host`` only (default ``127.0.0.1``: reachable from this machine only);
* the ZeroMQ command socket always on 127.0.0.1 (whoever reaches it can draw in the scene);
* ``--parent PID``: the server stops by itself when that process is gone, so even a killed
  viewer (SIGKILL) leaves no server behind;
* SIGTERM, SIGHUP and SIGINT stop it cleanly.

It prints ``zmq_url=...`` and ``web_url=...`` like meshcat's server, so :class:`h4pin.mechanism.scene.Scene`
reads them the same way. Run by :func:`start`, not by hand (``python -m h4pin.mechanism.meshcat_server``).
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile

LOCALHOST = "127.0.0.1"


def _bridge_class():
    from meshcat.servers.zmqserver import ZMQWebSocketBridge

    class Bridge(ZMQWebSocketBridge):
        """meshcat's bridge with the web server on ``self.host`` and ZeroMQ on 127.0.0.1."""

        def make_app(self):
            app = super().make_app()
            listen, host = app.listen, self.host
            app.listen = lambda port, **kwargs: listen(port, address=host, **kwargs)
            return app

        def setup_zmq(self, url):
            scheme, _, rest = url.partition("://")
            return super().setup_zmq(f"{scheme}://{LOCALHOST}:{rest.rsplit(':', 1)[1]}")

    return Bridge


def main(argv: list[str] | None = None) -> None:
    """Run the server until SIGTERM, SIGHUP, SIGINT or the end of ``--parent``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--host", default=LOCALHOST, help="interface of the web server (default: 127.0.0.1)")
    parser.add_argument("--parent", type=int, default=None, help="stop when this process is gone")
    args = parser.parse_args(argv)

    import tornado.ioloop

    bridge = _bridge_class()(host=args.host)
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)
    loop = bridge.ioloop

    def stop(*_: object) -> None:
        loop.add_callback(loop.stop)  # signal-safe since tornado 6.3

    for sig in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT):
        signal.signal(sig, stop)
    if args.parent is not None:
        def check_parent() -> None:
            if os.getppid() != args.parent:  # re-parented: the viewer that started us is gone
                loop.stop()

        tornado.ioloop.PeriodicCallback(check_parent, 500).start()
    bridge.run()


def check_host(host: str) -> None:
    """Refuse, at once, an interface this machine cannot listen on (an invalid address, a name
    that does not resolve, another machine's address): one bind on port 0, no port scan.

    Raises:
        h4pin.ParameterError: naming the host and the reason.
    """
    import socket

    from h4pin.errors import ParameterError

    try:
        infos = socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM)
        family, kind, proto, _, address = infos[0]
        with socket.socket(family, kind, proto) as sock:
            sock.bind(address)
    except (OSError, UnicodeError, ValueError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc)
        raise ParameterError(f"--host {host}: this machine cannot listen there ({reason}); give one of its "
                             "addresses, e.g. 127.0.0.1 (this machine only) or 0.0.0.0 (every interface)") from None


def start(host: str = LOCALHOST) -> tuple[subprocess.Popen, str, str]:
    """Start a server for this process; returns (process, zmq_url, web_url).

    The server runs in its own session (a Ctrl-C in Jupyter does not reach it) and stops when
    this process ends. The caller owns the process: terminate it to stop the server.

    Raises:
        h4pin.ParameterError: ``host`` is not an interface of this machine (:func:`check_host`).
        RuntimeError: the server exited before printing its addresses (its stderr is quoted).
    """
    check_host(host)
    err = tempfile.TemporaryFile()
    proc = subprocess.Popen([sys.executable, "-u", "-m", "h4pin.mechanism.meshcat_server", "--host", host,
                             "--parent", str(os.getpid())],
                            stdout=subprocess.PIPE, stderr=err, stdin=subprocess.DEVNULL, start_new_session=True)
    try:
        urls: dict[str, str] = {}
        while len(urls) < 2:
            line = proc.stdout.readline().decode("utf-8", "replace").strip()
            if not line and proc.poll() is not None:
                err.seek(0)
                tail = err.read().decode("utf-8", "replace").strip().splitlines()[-1:]
                raise RuntimeError(f"the meshcat server exited with status {proc.returncode}"
                                   + (f": {tail[0]}" if tail else ""))
            key, sep, value = line.partition("=")
            if sep and key in ("zmq_url", "web_url"):
                urls[key] = value
    except BaseException:
        stop(proc)
        raise
    finally:
        err.close()
    return proc, urls["zmq_url"], urls["web_url"]


def stop(proc: subprocess.Popen, timeout: float = 5.0) -> None:
    """Stop a server from :func:`start` and reap it (SIGTERM, then SIGKILL after ``timeout`` s)."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    if proc.stdout is not None:
        proc.stdout.close()


if __name__ == "__main__":
    main()
