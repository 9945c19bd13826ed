"""The dashboard's web server (Starlette on uvicorn): a static page and the fleet's state as it changes.

    GET /                                  the page (static/index.html, its script and style beside it)
    GET /events                            server-sent events: the state document (live.py) on each change
    GET /api/state                         the state document once
    GET /api/logs/FLEET/ROBOT              the robot's recent log lines (the request of `fleet logs`)
    GET /api/params/FLEET/ROBOT            its parameters as deployed, with live overrides
    GET /api/param/FLEET/ROBOT/NODE/NAME   one parameter's live value (the request of `fleet param get`)

Read-only: nothing here changes the fleet.  Requests to agents block on Zenoh, so they run in
worker threads; the event loop only moves documents.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import json
import logging
import signal
import socket
from pathlib import Path
from typing import Any

from pydantic import ValidationError
from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, StreamingResponse
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from fleet.dashboard.live import LiveFleet, UnknownRobot
from fleet.errors import BadRequest, ControlError, FleetError
from fleet.wire.protocol import short_validation_error

log = logging.getLogger("fleet.dashboard")

STATIC = Path(__file__).parent / "static"
MIN_INTERVAL = 0.1  # s between two documents: a burst of changes becomes one
KEEP_ALIVE = 15.0  # s: a comment line on a quiet stream, so proxies and browsers keep it open
LOG_TAIL = 40


class Latest:
    """The newest state document, and a way for each event stream to wait for the next one."""

    def __init__(self) -> None:
        self.version = 0
        self.data = b""
        self._changed = asyncio.Event()

    def publish(self, data: bytes) -> None:
        self.version += 1
        self.data = data
        self._changed.set()
        self._changed = asyncio.Event()

    async def wait_newer(self, version: int, timeout: float) -> bool:
        if self.version != version:
            return True
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(self._changed.wait(), timeout)
        return self.version != version


def create_app(live: LiveFleet) -> Starlette:
    latest = Latest()

    async def pump(changed: asyncio.Event) -> None:
        while True:
            await changed.wait()
            changed.clear()
            try:
                document = await asyncio.to_thread(live.snapshot)
                latest.publish(json.dumps(document, separators=(",", ":"), default=str).encode())
            except Exception:  # a bad document must not stop the stream: the next change tries again
                log.exception("cannot build the state document")
            await asyncio.sleep(MIN_INTERVAL)

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette):
        loop = asyncio.get_running_loop()
        changed = asyncio.Event()

        def on_change() -> None:  # on a Zenoh thread
            with contextlib.suppress(RuntimeError):  # the loop is closing
                loop.call_soon_threadsafe(changed.set)

        live.on_change = on_change
        task = asyncio.create_task(pump(changed))
        live.start()
        try:
            yield
        finally:
            live.on_change = lambda: None
            task.cancel()
            await asyncio.to_thread(live.close)

    async def page(request: Request) -> FileResponse:
        return FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-store"})

    async def events(request: Request) -> StreamingResponse:
        async def stream():
            version = 0
            while True:
                if await latest.wait_newer(version, KEEP_ALIVE):
                    version = latest.version
                    yield b"data: " + latest.data + b"\n\n"
                else:
                    yield b": keep-alive\n\n"

        headers = {"Cache-Control": "no-store", "X-Accel-Buffering": "no"}
        return StreamingResponse(stream(), media_type="text/event-stream", headers=headers)

    async def state(request: Request) -> JSONResponse:
        return JSONResponse(await asyncio.to_thread(live.snapshot))

    async def logs(request: Request) -> JSONResponse:
        fleet, robot = request.path_params["fleet"], request.path_params["robot"]
        return await _answer(live.logs, fleet, robot, LOG_TAIL)

    async def params(request: Request) -> JSONResponse:
        return await _answer(live.deployed_parameters, request.path_params["fleet"], request.path_params["robot"])

    async def param(request: Request) -> JSONResponse:
        keys = ("fleet", "robot", "node", "name")
        return await _answer(live.parameter, *(request.path_params[key] for key in keys))

    routes = [
        Route("/", page),
        Route("/events", events),
        Route("/api/state", state),
        Route("/api/logs/{fleet}/{robot}", logs),
        Route("/api/params/{fleet}/{robot}", params),
        Route("/api/param/{fleet}/{robot}/{node}/{name}", param),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
    ]
    return Starlette(routes=routes, lifespan=lifespan)


async def _answer(function, *args: Any) -> JSONResponse:
    """A blocking request to the fleet, in a worker thread; its failure as {"error": ...}: 404 for
    a robot, node or parameter the fleet does not have, 502 when the fleet failed to answer, 400
    for a bad request."""
    try:
        return JSONResponse(await asyncio.to_thread(function, *args))
    except (UnknownRobot, BadRequest) as error:  # BadRequest: the agent does not know what was named
        return JSONResponse({"error": str(error)}, status_code=404)
    except ControlError as error:  # the agent or the router did not answer, or refused
        return JSONResponse({"error": str(error)}, status_code=502)
    except ValidationError as error:  # pydantic refused the request (a bad parameter name): in its words
        return JSONResponse({"error": short_validation_error(error)}, status_code=400)
    except ValueError as error:
        return JSONResponse({"error": str(error).splitlines()[0]}, status_code=400)


def listen(host: str, port: int) -> socket.socket:
    """A listening socket, bound here so a port in use is one clear error (port 0: any free one)."""
    try:
        family, kind, _, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
    except socket.gaierror as error:
        raise FleetError(f"dashboard: cannot listen on {host!r}: {error.strerror}") from None
    sock = socket.socket(family, kind)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # restart at once; two listeners still clash
    try:
        sock.bind(address)
        sock.listen(128)
    except OSError as error:
        sock.close()
        if error.errno == errno.EADDRINUSE:
            raise FleetError(
                f"dashboard: port {port} on {host} is in use (another program listens there): "
                f"pick another with --port, or --port 0 for a free one"
            ) from None
        raise FleetError(f"dashboard: cannot listen on port {port} of {host}: {error.strerror}") from None
    return sock


def url_of(sock: socket.socket) -> str:
    host, port = sock.getsockname()[:2]
    return f"http://[{host}]:{port}/" if ":" in host else f"http://{host}:{port}/"


def serve(live: LiveFleet, sock: socket.socket) -> None:
    """Serve until SIGINT or SIGTERM, then close the live view and return."""
    import uvicorn

    class Server(uvicorn.Server):
        @contextlib.contextmanager
        def capture_signals(self):
            # uvicorn's own raises the signal again once stopped; a stop asked for is a clean
            # exit here, as for the other daemons (a second signal still forces the exit).
            for signum in (signal.SIGINT, signal.SIGTERM):
                signal.signal(signum, self.handle_exit)
            yield

    config = uvicorn.Config(create_app(live), log_level="warning", timeout_graceful_shutdown=1)
    Server(config).run(sockets=[sock])
