"""Daemon settings: one schema, read from a YAML file and ``MOMLOC_*`` environment variables.

Design (config as schema): pydantic models mirror the YAML tree, reject unknown keys and carry a
description on every field, so a settings file validates itself at start and documents itself
(`Settings.model_json_schema()`). Precedence, highest first: command-line overrides (``--host``,
``--port``), environment (``MOMLOC_PORT=9000``, nested with ``__``:
``MOMLOC_DETECTOR__SCORE_THRESHOLD=0.5``), the YAML file, then the defaults below.

Error policy: every invalid setting becomes one line ``<field>: <problem>`` inside a single
:class:`MomlocError`, so ``momloc serve`` prints them all at once and exits 2.

Example ``momloc.yaml``::

    cameras:
      - {type: v4l2, device: /dev/video0}
      - {type: v4l2, device: /dev/video1}
    model_dir: ./my_model
    token: change-me
"""

from __future__ import annotations

import contextvars
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

import yaml
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SecretStr,
    ValidationError,
    field_validator,
    model_validator,
)
from pydantic_settings import BaseSettings, PydanticBaseSettingsSource, SettingsConfigDict

from common.errors import MomlocError
from models.detector.nanodet import NanoDetSettings
from models.detector.ssdlite import SsdliteSettings
from models.detector.yolov8 import Yolov8Settings
from service.outputs.settings import FallSettings, MqttSettings, OscSettings, ZoneList
from service.tracking.association import DEFAULT_MAX_ERROR_PX

DEMO_MODEL_DIR = Path(__file__).resolve().parent.parent / "models" / "demo_model"
_STRICT = ConfigDict(extra="forbid")
Privacy = Literal["off", "positions_only"]
POSITIONS_ONLY: Privacy = "positions_only"
_ORIGIN = r"^(\*|https?://[A-Za-z0-9.\-\[\]:]+)$"
_HOST = r"^(\*|[A-Za-z0-9.\-]+|\[?[0-9A-Fa-f:.]+\]?)$"


class V4l2Camera(BaseModel):
    """A USB webcam read through V4L2."""

    model_config = _STRICT
    type: Literal["v4l2"] = Field(description="Source kind: a V4L2 webcam.")
    device: str = Field(description="Device path (/dev/video0) or index (0).")
    width: int = Field(640, ge=16, le=7680, description="Requested frame width in pixels.")
    height: int = Field(480, ge=16, le=4320, description="Requested frame height in pixels.")
    fps: float = Field(30.0, gt=0, le=240, description="Requested frame rate.")
    name: str | None = Field(None, description="Display name; defaults to the device.")


class FileCamera(BaseModel):
    """A video file, or a camera of a ``momloc record`` folder replayed with its recorded timing
    (``capture.replay``)."""

    model_config = _STRICT
    type: Literal["file"] = Field(description="Source kind: a video file.")
    path: Path = Field(
        description="Video file (anything OpenCV can decode; a recording's camN.avi replays "
        "with the camN.csv timestamps beside it) or a momloc record folder (with camera)."
    )
    loop: bool = Field(True, description="Start again at the end instead of disconnecting.")
    fps: float | None = Field(
        None,
        gt=0,
        le=240,
        description="Fixed playback rate; default: the recorded timing (momloc record) or the "
        "file's rate.",
    )
    camera: int | None = Field(
        None, ge=0, le=8, description="Which camera, when path is a momloc record folder."
    )
    name: str | None = Field(None, description="Display name; defaults to the file name.")


class SyntheticCamera(BaseModel):
    """Camera ``index`` of the simulated scene described in the ``synthetic`` section."""

    model_config = _STRICT
    type: Literal["synthetic"] = Field(description="Source kind: a simulated camera.")
    index: int = Field(ge=0, le=8, description="Camera index inside the simulated scene.")
    name: str | None = Field(None, description="Display name; defaults to synthetic-<index>.")


CameraSettings = Annotated[V4l2Camera | FileCamera | SyntheticCamera, Field(discriminator="type")]


# One settings class per detector kind, in the kind's plugin module (after Frigate's detector
# plugins), told apart by ``kind``; a detector section without ``kind`` is NanoDet's.
_DETECTOR_CLASSES = (NanoDetSettings, SsdliteSettings, Yolov8Settings)
DetectorSettings = Annotated[
    NanoDetSettings | SsdliteSettings | Yolov8Settings, Field(discriminator="kind")
]
DETECTOR_KINDS = tuple(get_args(c.model_fields["kind"].annotation)[0] for c in _DETECTOR_CLASSES)


class DetectionSettings(BaseModel):
    """When the detector runs (see ``service.detection.schedule``)."""

    model_config = _STRICT
    schedule: Literal["auto", "every_frame"] = Field(
        "auto",
        description=(
            "auto: the detector runs beside the pipeline on the newest frame set whenever it is "
            "free, and boxes are carried between detections (Kalman filter + optical flow), so "
            "every frame set is published at the cameras' rate (the detector then uses one "
            "onnxruntime thread unless detector.threads is set); every_frame: one inline "
            "detector call per frame set (slower than the cameras on small machines)."
        ),
    )
    max_duty: float = Field(
        1.0,
        gt=0.0,
        le=1.0,
        description="auto: largest share of time the detector may be busy (1: whenever free).",
    )
    cameras_per_call: int = Field(
        0, ge=0, le=9, description="auto: frames per detector call (0: all cameras, 1: alternate)."
    )
    flow: bool = Field(
        True, description="auto: carry boxes with Lucas-Kanade optical flow, not the filter alone."
    )
    max_age_s: float = Field(
        0.5, gt=0.0, le=10.0, description="auto: drop a box the detector has not seen this long."
    )
    nice: int = Field(
        10,
        ge=0,
        le=19,
        description=(
            "auto: lower the detector thread's priority by this much (Linux), so the cameras and "
            "the pipeline run first when the CPU is short (0: same priority)."
        ),
    )
    windows: int = Field(
        0,
        ge=0,
        le=16,
        description=(
            "auto, nanodet: after each detection, look again at up to this many known people "
            "shorter than window_below_px in 96x160 windows: small people get a sharper "
            "bottom edge and fewer false boxes, but each window costs CPU and the detector "
            "runs less often (bench/results/small_people.md). 0: off."
        ),
    )
    window_below_px: float = Field(
        150.0, gt=0.0, le=2000.0, description="auto: people at least this tall get no window."
    )


class SyntheticSettings(BaseModel):
    """The simulated scene used by ``synthetic`` cameras and ``momloc demo``."""

    model_config = _STRICT
    preset: str = Field("indoor-2cam", description="Simulator preset (models.simulate.PRESETS).")
    seed: int = Field(7, description="Scene random seed: same seed, same people and paths.")
    people: int = Field(3, ge=0, le=20, description="Number of walking people.")
    fps: float = Field(30.0, gt=0, le=120, description="Scene frame rate (frames per second).")
    detections: Literal["rendered", "simulated"] = Field(
        "simulated",
        description=(
            "rendered: frames drawn by the simulator go through the real detector; "
            "simulated: the simulator's noisy boxes enter the pipeline instead of detector output."
        ),
    )
    detector_profile: str = Field(
        "nanodet",
        description=(
            "How blind the simulated detector is (simulated detections): a shipped profile "
            "(nanodet, ssdlite, ideal) or a profile JSON path; see models/simulate/profile.py."
        ),
    )
    follow_setup: bool = Field(
        False,
        description=(
            "One simulated person who follows the /setup page's instructions (goes to each "
            "mark, stands on it) instead of random walkers: the set-up flow without a human."
        ),
    )
    preview_fps: float = Field(
        5.0,
        ge=0,
        le=120,
        description=(
            "With simulated detections, draw frames for the camera previews this often "
            "(0: never); rendered detections draw every frame."
        ),
    )


class StreamSettings(BaseModel):
    """WebSocket stream behaviour."""

    model_config = _STRICT
    rate: float = Field(30.0, gt=0, le=240, description="Default and maximum snapshots/s.")
    ping_interval: float = Field(
        20.0, gt=0, le=3600, description="Seconds between WebSocket keep-alive pings."
    )
    ping_timeout: float = Field(
        20.0, gt=0, le=3600, description="Seconds to wait for a pong before closing."
    )


class TrackingSettings(BaseModel):
    """Tracker and association options."""

    model_config = _STRICT
    max_missing_s: float = Field(
        1.5, gt=0, le=60, description="Keep an unseen person's id this many seconds."
    )
    max_skew_s: float = Field(
        0.05,
        gt=0,
        le=5,
        description="A camera's frame more than this older than the newest frame of its set is "
        "left out of fusion (the set is localized as one instant from the others). 0.05 s: a "
        "walking person moves 7 cm in it, less than the localizer's error, and unsynchronised "
        "30 fps webcams are at most 33 ms apart, so their sets are fused whole.",
    )
    max_error_px: float = Field(
        DEFAULT_MAX_ERROR_PX,
        gt=0,
        description="Largest reprojection error (px, scaled to a 200 px box) for a match.",
    )
    outside_area: Literal["drop", "flag"] = Field(
        "drop",
        description="People outside the floor area the model was set up on (its floor marks "
        "plus a margin, where its cameras saw training boxes): 'drop' leaves them out of "
        "tracking and every output; 'flag' tracks them and serves them with outside: true "
        "(the map shows them; zones and MQTT ignore them).",
    )


class FloorSettings(BaseModel):
    """Floor area drawn on the live map, in metres (default: fitted to the model's data)."""

    model_config = _STRICT
    xmin: float = Field(description="Left edge of the map (m).")
    xmax: float = Field(description="Right edge of the map (m).")
    ymin: float = Field(description="Bottom edge of the map (m).")
    ymax: float = Field(description="Top edge of the map (m).")

    @model_validator(mode="after")
    def _ordered(self) -> FloorSettings:
        if self.xmax <= self.xmin or self.ymax <= self.ymin:
            raise ValueError("xmax must exceed xmin and ymax must exceed ymin")
        return self


class LearningSettings(BaseModel):
    """The room that learns from people walking (``service.learning``; docs:
    concepts/learning-room.md)."""

    model_config = _STRICT
    enabled: bool = Field(
        True,
        description="Keep self-labels: moments where two or more cameras localize a person well "
        "(data_dir/learning/<room>/), counted in /v1/health learning.self_labels.",
    )
    max_mb: float = Field(
        50.0, gt=0, le=100_000, description="Disk cap of the self-label store; oldest go first."
    )
    min_views: int = Field(2, ge=2, le=9, description="Cameras that must see a labelled person.")
    max_std_m: float = Field(
        0.15, gt=0, le=5, description="Largest position std (m) the localizer may report."
    )
    max_cost: float = Field(
        40.0, gt=0, description="Largest association cost (normalised px) of a labelled person."
    )
    min_separation_m: float = Field(
        1.0, ge=0, le=10, description="Nobody else may be this close to a labelled person."
    )
    min_interval_s: float = Field(
        0.5, ge=0, le=60, description="At most one label per person this often."
    )
    improve: bool = Field(
        True,
        description="Retrain on floor marks + self-labels in the background and serve the new "
        "model only when it is no worse on the marks and better on held-out self-labels.",
    )
    improve_every_labels: int = Field(
        2000, ge=100, description="Run once this many new self-labels were kept."
    )
    improve_nice: int = Field(
        19, ge=0, le=19, description="CPU priority cap of the training child (nice increment)."
    )
    improve_time_budget_s: float = Field(
        120.0,
        gt=0,
        le=3600,
        description="Wall-clock cap of the adaptive schedule: training stops after this long, "
        "keeping its best epoch (not with improve_epochs).",
    )
    improve_epochs: int | None = Field(
        None,
        ge=1,
        le=10_000,
        description="Train at most this many epochs (early stopping may end sooner) instead of the "
        "adaptive schedule and its time budget: the same work on a busy machine as on an idle one.",
    )
    heal: bool = Field(
        True,
        description="When a camera is flagged as moved, re-learn its floor map from the "
        "positions the other cameras give and serve the repair once its check passes.",
    )
    heal_min_positions: int = Field(
        120, ge=20, le=100_000, description="Positions to collect before the first repair."
    )
    marks: Path | None = Field(
        None,
        description="Floor-mark recording (.npz) the improvement trains on and is checked "
        "against; default: the newest recording in data_dir.",
    )


_yaml_data: contextvars.ContextVar[dict[str, Any] | None] = contextvars.ContextVar(
    "yaml", default=None
)


class _YamlSource(PydanticBaseSettingsSource):
    """Feeds the already-parsed YAML mapping in at the lowest precedence."""

    def get_field_value(self, field: Any, field_name: str) -> tuple[Any, str, bool]:
        return (_yaml_data.get() or {}).get(field_name), field_name, False

    def __call__(self) -> dict[str, Any]:
        return dict(_yaml_data.get() or {})


class Settings(BaseSettings):
    """Everything ``momloc serve`` needs; ``momloc demo`` builds one for the synthetic scene."""

    model_config = SettingsConfigDict(
        env_prefix="MOMLOC_", env_nested_delimiter="__", extra="forbid", validate_default=True
    )
    cameras: list[CameraSettings] = Field(
        min_length=1, max_length=9, description="Cameras in model order (1 to 9)."
    )
    model_dir: Path | None = Field(
        None,
        description=(
            "Directory with encoder.onnx and model.json (momloc train). Absent: the model the "
            "/setup page trained (data_dir/model), else set-up mode (no positions until one is)."
        ),
    )

    detector: DetectorSettings = Field(
        default_factory=NanoDetSettings,
        description="Person detector: kind (nanodet, ssdlite, yolov8; nanodet when not given) and "
        "that kind's options.",
    )
    detection: DetectionSettings = Field(
        default_factory=DetectionSettings, description="Detection scheduling options."
    )
    host: str = Field("127.0.0.1", min_length=1, description="Bind address (0.0.0.0: all).")
    port: int = Field(8765, ge=1, le=65535, description="TCP port of the HTTP/WebSocket API.")
    token: SecretStr | None = Field(
        None, description="API token; when set, every /v1 request and /metrics must carry it."
    )
    allowed_origins: list[Annotated[str, Field(pattern=_ORIGIN, max_length=200)]] = Field(
        default_factory=list,
        max_length=100,
        description=(
            "Web origins (scheme://host[:port]) besides the daemon's own whose pages may use the "
            "API and the stream, e.g. http://localhost:3000; '*' allows every origin. Requests "
            "without an Origin header (game engines, scripts, curl) are always allowed."
        ),
    )
    allowed_hosts: list[Annotated[str, Field(pattern=_HOST, max_length=253)]] = Field(
        default_factory=list,
        max_length=100,
        description=(
            "Host names (besides IP addresses, localhost, this machine's name and the bind "
            "address) that requests may be addressed to; guards against DNS rebinding. '*': any."
        ),
    )
    stream: StreamSettings = Field(
        default_factory=StreamSettings, description="WebSocket stream options."
    )
    tracking: TrackingSettings = Field(
        default_factory=TrackingSettings, description="Tracking and association options."
    )
    synthetic: SyntheticSettings = Field(
        default_factory=SyntheticSettings, description="Simulated scene for synthetic cameras."
    )
    floor: FloorSettings | None = Field(None, description="Map extent; default from the model.")
    data_dir: Path = Field(
        Path("momloc-data"), description="Where the /setup page writes floor-mark recordings."
    )
    watch_model: bool = Field(
        True, description="Reload the model when momloc train rewrites model_dir."
    )
    learning: LearningSettings = Field(
        default_factory=LearningSettings,
        description="Self-labels, self-improvement and self-healing of the model.",
    )
    # -- outputs beyond the API: zones and MQTT (models in service.outputs.settings) --------------
    zones: ZoneList = Field(
        default_factory=list, description="Named floor polygons with occupancy and events."
    )
    falls: FallSettings = Field(
        default_factory=FallSettings, description="The fall event (standing to lying, then down)."
    )
    mqtt: MqttSettings | None = Field(None, description="MQTT publisher; absent: off.")
    osc: OscSettings | None = Field(None, description="OSC bundles over UDP; absent: off.")
    privacy: Privacy = Field(
        "off",
        description="positions_only: the daemon serves and stores no camera images (no "
        "snapshot JPEGs, previews drawn as boxes on an empty background, no momloc record); "
        "positions, zones, events and the set-up flow work as before. off: previews and "
        "recordings allowed (docs/guides/security.md).",
    )

    @classmethod
    def settings_customise_sources(
        cls,
        settings_cls: type[BaseSettings],
        init_settings: PydanticBaseSettingsSource,
        env_settings: PydanticBaseSettingsSource,
        dotenv_settings: PydanticBaseSettingsSource,
        file_secret_settings: PydanticBaseSettingsSource,
    ) -> tuple[PydanticBaseSettingsSource, ...]:
        return init_settings, env_settings, _YamlSource(settings_cls)

    @field_validator("model_dir")
    @classmethod
    def _path_fits_the_os(cls, value: Path | None) -> Path | None:
        """A path the OS cannot hold is a settings error, not an OSError deep in loading."""
        if value is None:
            return None
        if len(str(value)) > 4096 or any(len(part.encode()) > 255 for part in value.parts):
            raise ValueError("path too long (at most 255 bytes per name, 4096 in all)")
        return value

    @field_validator("detector", mode="before")
    @classmethod
    def _nanodet_unless_told(cls, value: Any) -> Any:
        """A detector section without ``kind`` (or an environment override alone) is NanoDet's."""
        if isinstance(value, dict) and "kind" not in value:
            return {"kind": "nanodet", **value}
        return value

    @model_validator(mode="after")
    def _synthetic_indices_unique(self) -> Settings:
        indices = [c.index for c in self.cameras if isinstance(c, SyntheticCamera)]
        if len(indices) != len(set(indices)):
            raise ValueError("cameras: a synthetic camera index appears twice")
        return self

    def token_value(self) -> str | None:
        """The token as plain text (``None``: authentication off)."""
        return self.token.get_secret_value() if self.token else None


def format_validation_error(error: ValidationError, origin: str = "settings") -> str:
    """One line per invalid field: ``<origin>: <dotted.field>: <problem>``."""
    lines = []
    for item in error.errors():
        loc = ".".join(str(part) for part in item["loc"] if part not in _UNION_TAGS) or "(root)"
        message = item["msg"].removeprefix("Value error, ")
        lines.append(f"{origin}: {loc}: {message}")
    return "\n".join(lines)


_UNION_TAGS = {"v4l2", "file", "synthetic", *DETECTOR_KINDS}


def read_yaml(path: Path, what: str) -> Any:
    """The YAML document in ``path``; an unreadable file or bad YAML is one MomlocError line
    (``what`` names the file's role; the line of a YAML error, never its echo of the text)."""
    try:
        return yaml.safe_load(path.read_text())
    except OSError as error:
        raise MomlocError(f"{path}: cannot read {what} ({error.strerror})") from None
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark else ""
        raise MomlocError(f"{path}: not valid YAML{where}") from None


def load_settings(path: str | Path | None = None, **overrides: Any) -> Settings:
    """Read ``path`` (YAML, optional) plus the environment; ``overrides`` win (None = not given)."""
    data: dict[str, Any] = {}
    origin = "settings"
    if path is not None:
        path = Path(path)
        origin = str(path)
        loaded = read_yaml(path, "settings file")
        if loaded is not None and not isinstance(loaded, dict):
            raise MomlocError(f"{path}: the top level must be a mapping of settings")
        data = loaded or {}
    token = _yaml_data.set(data)
    try:
        return Settings(**{k: v for k, v in overrides.items() if v is not None})
    except ValidationError as error:
        raise MomlocError(format_validation_error(error, origin)) from None
    finally:
        _yaml_data.reset(token)
