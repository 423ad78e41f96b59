"""The operator station's web application (Flask): the cell now, the records, the actions.

Server-rendered pages (Jinja templates, no external assets: the cell may have no internet) and a
little JavaScript that polls ``/api/status`` four times a second so the state is live without a
reload. Actions are POST requests with a CSRF token and the operator role; they are the control
requests of ``seamguide ctl`` (:meth:`DaemonPort.handle_request`), with the same semantics: no
answer to a waiting weld path, an abort or a shutdown is a no. Every refused request is logged.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from flask import Flask, Response, abort, jsonify, redirect, render_template, request, send_file

from controller.errors import InputError
from controller.station.access import COOKIE, Access
from controller.station.records_view import (
    OUTCOMES,
    list_records,
    read_record_doc,
    record_dir,
    record_file,
)

log = logging.getLogger("seamguide.station")

ACTIONS = ("start", "abort", "pause", "resume", "confirm", "reject")


class DaemonPort(Protocol):
    """What the station needs of the daemon: its status and its control requests."""

    def status(self) -> dict[str, Any]:
        """The ``seamguide ctl status`` answer."""

    def handle_request(self, req: dict[str, Any]) -> dict[str, Any]:
        """Answer one control request (``{"cmd": ..., "job": ...}``)."""


@dataclass(frozen=True)
class StationSettings:
    """What the pages show besides the status: records, calibration, jobs; request bound."""

    cell: str
    records_dir: str
    calibration_path: str
    jobs: tuple[str, ...]
    max_request_bytes: int = 16384


def calibration_summary(path: str, now: float | None = None) -> dict[str, Any]:
    """Date, age (days) and the quality figures stored in a calibration file's ``metadata``."""
    import yaml

    p = Path(path)
    out: dict[str, Any] = {"file": p.name}
    try:
        doc = yaml.safe_load(p.read_text(encoding="utf-8")) or {}
        mtime = p.stat().st_mtime
    except (OSError, yaml.YAMLError) as err:
        return {"file": p.name, "error": str(err)}
    meta = doc.get("metadata") if isinstance(doc, dict) else None
    meta = meta if isinstance(meta, dict) else {}
    out["date"] = str(meta.get("date") or meta.get("created") or
                      time.strftime("%Y-%m-%d %H:%M", time.localtime(mtime)))
    out["age_days"] = round(((now or time.time()) - mtime) / 86400.0, 2)
    out["age_s"] = (now or time.time()) - mtime
    for key in ("reprojection_px_rms", "rms_px", "hand_eye_std_mm", "hand_eye_std_deg",
                "hand_eye_std_mm_cam_xyz", "source"):
        if key in meta:
            out[key] = meta[key]
    return out


def create_app(port: DaemonPort, settings: StationSettings, access: Access,
               metrics_text: Callable[[], bytes] | None = None) -> Flask:
    """The Flask application of the station (served by :mod:`controller.station.server`)."""
    app = Flask(__name__)
    app.config["MAX_CONTENT_LENGTH"] = settings.max_request_bytes
    records = Path(settings.records_dir)

    def credential() -> str | None:
        auth = request.headers.get("Authorization", "")
        if auth.startswith("Bearer "):
            return auth[7:].strip()
        return request.cookies.get(COOKIE)

    def role() -> str | None:
        return access.role(credential())

    def refuse(code: int, why: str) -> Response:
        log.warning("refused %s %s from %s: %s", request.method, request.path,
                    request.remote_addr, why)
        if request.path.startswith("/api/") or request.method == "POST" or code == 413:
            resp = jsonify({"ok": False, "error": why})
            resp.status_code = code
            return resp
        return Response(render_template("error.html", code=code, why=why, role=role()),
                        status=code)

    @app.before_request
    def _gate() -> Any:
        if request.endpoint in ("login", "static"):
            return None
        if role() is None:
            if request.method == "GET" and not request.path.startswith(("/api/", "/metrics")):
                log.warning("refused %s %s from %s: not logged in", request.method,
                            request.path, request.remote_addr)
                return redirect("/login")
            return refuse(401, "a viewer or operator token is needed")
        return None

    @app.errorhandler(413)
    def _too_large(_err: Exception) -> Response:
        return refuse(413, f"request larger than {settings.max_request_bytes} bytes")

    @app.errorhandler(404)
    def _not_found(_err: Exception) -> Response:
        return refuse(404, "no such page")

    @app.errorhandler(405)
    def _bad_method(_err: Exception) -> Response:
        return refuse(405, "method not allowed")

    def page(template: str, **kw: Any) -> str:
        return render_template(template, role=role(), cell=settings.cell,
                               csrf=access.csrf_token(credential()), open=access.open, **kw)

    @app.get("/")
    def cell_now() -> str:
        return page("cell.html", jobs=settings.jobs, status=port.status(),
                    calibration=calibration_summary(settings.calibration_path),
                    recent=list_records(records, limit=8))

    @app.get("/api/status")
    def api_status() -> Response:
        st = dict(port.status())
        st["role"] = role()
        st["calibration"] = calibration_summary(settings.calibration_path)
        st["server_time"] = time.time()
        return jsonify(st)

    @app.route("/login", methods=["GET", "POST"])
    def login() -> Any:
        if request.method == "GET":
            return render_template("login.html", role=None, cell=settings.cell, open=access.open,
                                   error=None)
        token = request.form.get("token", "")
        if access.role(token) is None or access.open:
            log.warning("refused POST /login from %s: wrong token", request.remote_addr)
            return Response(render_template("login.html", role=None, cell=settings.cell,
                                            open=access.open, error="wrong token"), status=401)
        resp = redirect("/")
        resp.set_cookie(COOKIE, token, httponly=True, samesite="Strict",
                        secure=request.is_secure)
        return resp

    @app.post("/logout")
    def logout() -> Any:
        resp = redirect("/login")
        resp.delete_cookie(COOKIE)
        return resp

    @app.post("/action/<cmd>")
    def action(cmd: str) -> Any:
        if cmd not in ACTIONS:
            return refuse(404, f"unknown action {cmd!r}")
        if role() != "operator":
            return refuse(403, f"{cmd} needs the operator role")
        origin = request.headers.get("Origin")
        if origin and origin.split("://", 1)[-1] != request.host:
            return refuse(403, f"cross-site request from {origin}")
        token = request.headers.get("X-CSRF-Token") or request.form.get("csrf")
        if not access.csrf_ok(credential(), token):
            return refuse(403, "missing or wrong CSRF token; reload the page")
        req: dict[str, Any] = {"cmd": cmd}
        if cmd == "start":
            req["job"] = request.form.get("job") or (request.get_json(silent=True) or {}).get("job")
        answer = port.handle_request(req)
        log.info("operator action %s from %s: %s", cmd, request.remote_addr, answer)
        if request.headers.get("X-CSRF-Token"):
            resp = jsonify(answer)
            resp.status_code = 200 if answer.get("ok") else 409
            return resp
        return redirect("/")

    @app.get("/records")
    def records_page() -> str:
        outcome = request.args.get("outcome") or None
        job = request.args.get("job") or None
        text = request.args.get("q") or None
        rows = list_records(records, outcome=outcome, job=job, text=text)
        return page("records.html", rows=rows, outcomes=OUTCOMES, jobs=settings.jobs,
                    outcome=outcome or "", job=job or "", q=text or "")

    @app.get("/records/<name>")
    def record_page(name: str) -> Any:
        try:
            folder = record_dir(records, name)
        except InputError as err:
            return refuse(404, str(err))
        doc = read_record_doc(records, name)
        files = sorted(p.name for p in folder.iterdir() if p.is_file())
        views = [f[:-5] for f in files if f.endswith(".json") and f[:-5] + ".png" in files]
        return page("record.html", name=name, doc=doc, files=files, views=views,
                    has_path=(folder / "seam.json").is_file())

    @app.get("/records/<name>/files/<file>")
    def record_download(name: str, file: str) -> Any:
        try:
            path = record_file(records, name, file)
        except InputError as err:
            return refuse(404, str(err))
        return send_file(path, as_attachment=request.args.get("download") == "1")

    @app.get("/records/<name>/path/<view>.png")
    def record_path_view(name: str, view: str) -> Any:
        from controller.station.path_view import path_overlay_png

        try:
            png = path_overlay_png(record_dir(records, name), view)
        except InputError as err:
            return refuse(404, str(err))
        return Response(png, mimetype="image/png")

    @app.get("/metrics")
    def metrics() -> Any:
        if metrics_text is None:
            abort(404)
        return Response(metrics_text(), mimetype="text/plain; version=0.0.4")

    @app.after_request
    def _headers(resp: Response) -> Response:
        resp.headers.setdefault("Cache-Control", "no-store")
        resp.headers["X-Content-Type-Options"] = "nosniff"
        resp.headers["X-Frame-Options"] = "DENY"
        resp.headers["Content-Security-Policy"] = (
            "default-src 'self'; img-src 'self' data:; style-src 'self' 'unsafe-inline'; "
            "script-src 'self'")
        return resp

    return app
