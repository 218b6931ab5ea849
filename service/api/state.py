"""What the HTTP API reads about the running daemon: hub, pipeline and the setup's static facts.

Its own module so that ``service.api.app`` (the routes) depends on this state only, never on the
composition root ``service.daemon`` that builds it (which would be an import cycle: the
composition root serves the app through ``service.api.server``).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Any

from service.camera_health.reprojection import CameraMoved
from service.learning.room import LearningRoom
from service.outputs.wiring import Outputs
from service.pipeline.hub import Hub
from service.pipeline.live import Pipeline
from service.pipeline.model_watch import ModelWatcher
from service.settings import POSITIONS_ONLY, Privacy
from service.setup.session import SetupSession
from service.setup.training import TrainingJob
from service.setup.verify import Verifier

NO_MODEL = "no model yet: record floor marks at /setup"


@dataclass
class Daemon:
    """Everything the API reads: hub, pipeline and the static facts about the setup."""

    hub: Hub
    pipeline: Pipeline
    camera_names: list[str]
    token: str | None = None
    stream_rate: float = 30.0
    ping_interval: float = 20.0
    ping_timeout: float = 20.0
    floor: dict[str, float] | None = None
    extras: dict[str, Any] = field(default_factory=dict)
    started: float = field(default_factory=time.time)
    watcher: ModelWatcher | None = None
    setup: SetupSession | None = None
    bind_host: str = "127.0.0.1"  # with the two lists below: see service.api.request_guard
    allowed_hosts: list[str] = field(default_factory=list)
    allowed_origins: list[str] = field(default_factory=list)
    outputs: Outputs | None = None  # zones and the configured publishers
    training: TrainingJob | None = None  # the /setup page's Train button
    verifier: Verifier | None = None  # the /setup page's check step
    learning: LearningRoom | None = None  # self-labels (service.learning); None: turned off
    privacy: Privacy = "off"  # positions_only: no camera image leaves the process

    @property
    def images_allowed(self) -> bool:
        """Whether camera images may be served (settings ``privacy``)."""
        return self.privacy != POSITIONS_ONLY

    @property
    def setup_mode(self) -> bool:
        """No model is served: cameras, previews and /setup work, no positions are published."""
        return self.pipeline.runtime is None

    def camera_states(self) -> list[dict[str, Any]]:
        states = self.pipeline.rig.states()
        alignment = self.pipeline.alignment_status(self.camera_names)
        repairs = {} if self.learning is None else self.learning.repair_messages()
        out = []
        for k, state in enumerate(states):
            d = dataclasses.asdict(state) if dataclasses.is_dataclass(state) else dict(vars(state))
            d = {
                "index": k,
                "name": self.camera_names[k] if k < len(self.camera_names) else f"camera-{k}",
                "connected": bool(d.get("connected", False)),
                "fps": _round(d.get("fps")),
                "last_frame_age": _round(d.get("last_frame_age"), 3),
                "reconnects": int(d.get("reconnects") or 0),
                "error": d.get("error"),
                "alignment": _alignment(alignment[k]) if k < len(alignment) else None,
                "repair": repairs.get(k),  # self-healing (service.learning.healer)
            }
            out.append(d)
        return out

    def health(self) -> dict[str, Any]:
        cameras = self.camera_states()
        model = self.pipeline.model_info()
        pipeline = self.pipeline.stats()
        model["verification"] = None if self.verifier is None else self.verifier.stored()
        if self.setup_mode:
            model["message"] = NO_MODEL
        degraded = self.degraded()
        ok = (
            all(c["connected"] and not (c["alignment"] or {}).get("moved") for c in cameras)
            and model["loaded"]
            and model.get("compatible", False)
            and pipeline["running"]
            and pipeline["error"] is None
            and not degraded
        )
        return {
            "status": "setup" if self.setup_mode else "ok" if ok else "degraded",
            "degraded": degraded,
            "setup_mode": self.setup_mode,
            "privacy": self.privacy,
            "uptime_s": round(time.time() - self.started, 1),
            "cameras": cameras,
            "model": model,
            "pipeline": pipeline,
            "clients": self.hub.subscriber_count,
            "stream": self.hub.stream_stats(),
            "model_reload": None if self.watcher is None else self.watcher.last_reload,
            "learning": {"enabled": False} if self.learning is None else self.learning.stats(),
            **({} if self.outputs is None else self.outputs.health()),
            **self.extras,
        }

    def degraded(self) -> dict[str, str]:
        """Parts that work but not as they should, each with why: outputs that deliver nowhere
        (MQTT broker down) and the set-up's last recording when a write failed (full disk)."""
        out = {} if self.outputs is None else dict(self.outputs.degraded())
        fault = None if self.setup is None else self.setup.fault()
        if fault is not None:
            out["setup_recording"] = fault
        return out

    def public_config(self) -> dict[str, Any]:
        return {
            "cameras": [{"index": k, "name": n} for k, n in enumerate(self.camera_names)],
            "floor": self.floor,
            "stream_rate": self.stream_rate,
            "auth": self.token is not None,
            "setup_mode": self.setup_mode,
            "privacy": self.privacy,
            "zones": []
            if self.outputs is None
            else [z.as_dict() for z in self.outputs.zones.zones],
            **self.extras,
        }


def _alignment(state: CameraMoved) -> dict[str, Any]:
    """The camera-moved check as health JSON: image shift and reprojection error, what to do."""
    shift, error = state.shift, state.reprojection
    return {
        "moved": state.moved,
        "shift_px": _round(shift.shift_px, 1),
        "shift_confidence": _round(shift.confidence),
        "reference": shift.reference,
        "shift_moved": shift.moved,
        "reprojection_px": _round(error.error_px, 1),
        "usual_px": _round(error.baseline_px, 1),
        "reprojection_moved": error.moved,
        "message": state.message,
    }


def _round(value: Any, digits: int = 2) -> float | None:
    return None if value is None else round(float(value), digits)
