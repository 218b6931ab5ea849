"""Settings of the daemon's outputs beyond its own API: zones, MQTT, Home Assistant discovery, OSC.

Kept apart from ``service.settings`` (which only adds the two fields ``zones`` and ``mqtt``) so
that the core settings and these can change independently. Same rules as there: unknown keys are
rejected and every field carries a description (they show in ``/v1/settings/schema``).

Example ``momloc.yaml`` lines::

    zones:
      - {name: sofa, polygon: [[1, 1], [3, 1], [3, 2.5], [1, 2.5]]}
    mqtt:
      host: 192.168.1.10
      room: living-room
      home_assistant: {discovery: true}
    osc: {host: 127.0.0.1, port: 9000, rate: 30}

Environment variables work as for every setting: ``MOMLOC_MQTT__HOST=broker.local``,
``MOMLOC_MQTT__PORT=1884``, ``MOMLOC_MQTT__HOME_ASSISTANT__DISCOVERY=true``,
``MOMLOC_OSC__HOST=10.0.0.5``, ``MOMLOC_OSC__PORT=9000``, ``MOMLOC_OSC__RATE=60``,
``MOMLOC_ZONES='[{"name": "sofa", "polygon": [[1,1],[3,1],[3,2.5]]}]'``.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, SecretStr, field_validator

from service.outputs.falls import FallRules
from service.outputs.zones import DEFAULT_HOLD_S, validate_polygon

_STRICT = ConfigDict(extra="forbid")
# One MQTT topic level that is also a valid Home Assistant object id and a Prometheus label.
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$"


class ZoneSettings(BaseModel):
    """A named floor area; occupancy and enter/leave events are reported per zone."""

    model_config = _STRICT
    name: str = Field(
        pattern=NAME_PATTERN,
        description="Zone name: letters, digits, '-' and '_' (it becomes an MQTT topic level).",
    )
    polygon: list[tuple[float, float]] = Field(
        description="Floor polygon [[x, y], ...] in metres (floor-mark frame): at least 3 "
        "points, not self-intersecting; points on an edge count as inside.",
    )
    hold_s: float = Field(
        DEFAULT_HOLD_S,
        ge=0,
        le=60,
        description="Hysteresis: a person must be inside (or outside) this many seconds of "
        "capture time before entering (or leaving) is reported.",
    )

    @field_validator("polygon")
    @classmethod
    def _valid_polygon(cls, value: list[tuple[float, float]]) -> list[tuple[float, float]]:
        return validate_polygon(value)


def _unique_names(zones: list[ZoneSettings]) -> list[ZoneSettings]:
    names = [z.name for z in zones]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ValueError(f"zone names must be unique; repeated: {', '.join(repeated)}")
    return zones


ZoneList = Annotated[list[ZoneSettings], AfterValidator(_unique_names)]


_FALL = FallRules()


class FallSettings(BaseModel):
    """The ``fall`` event: standing to lying quickly, then lying (``service.outputs.falls``)."""

    model_config = _STRICT
    enabled: bool = Field(
        True,
        description="Report falls (needs postures: a model with a set-up area height model); "
        "with MQTT and Home Assistant discovery, a 'fall' binary_sensor for the room.",
    )
    max_drop_s: float = Field(
        _FALL.max_drop_s,
        gt=0,
        le=10,
        description="A fall starts when a person reads lying at most this long after standing.",
    )
    lying_s: float = Field(
        _FALL.lying_s,
        ge=0,
        le=600,
        description="... and is reported once they have read lying this long in all "
        "(seconds; a fall is to be reported within 3 s of the body reaching the floor).",
    )
    min_confidence: float = Field(
        _FALL.min_confidence,
        ge=0,
        le=1,
        description="... on a snapshot whose posture_confidence of lying is at least this "
        "(a sit-down or a crouch misread as lying reads lower).",
    )
    standing_confidence: float = Field(
        _FALL.standing_confidence,
        ge=0,
        le=1,
        description="A fall starts only from a standing read at least this sure (a track left "
        "where a sitter was reads standing unsurely).",
    )
    coast_s: float = Field(
        _FALL.coast_s,
        ge=0,
        le=60,
        description="A snapshot no camera sees the person in, at most this long after a sure "
        "lying read, counts as one once two cameras have read them lying for sure (seconds; "
        "the detector often misses a body just down; 0: off).",
    )
    clear_s: float = Field(
        _FALL.clear_s,
        gt=0,
        le=60,
        description="Standing this long clears a fall (sitting or standing this long drops one "
        "not yet reported).",
    )
    lost_s: float = Field(
        _FALL.lost_s,
        gt=0,
        le=3600,
        description="A fall whose person is no longer tracked for this long is cleared "
        "(reason 'lost').",
    )
    min_standing_s: float = Field(
        _FALL.min_standing_s,
        ge=0,
        le=60,
        description="A fall starts only after the person was seen standing this long "
        "(seconds; a track born a moment before is not yet known to be standing).",
    )
    upright_unseen_s: float = Field(
        _FALL.upright_unseen_s,
        gt=0,
        le=600,
        description="... and no camera seeing them for longer than this starts that anew "
        "(seconds; a track held where its person was is not known to be standing there).",
    )
    lying_gap_s: float = Field(
        _FALL.lying_gap_s,
        gt=0,
        le=600,
        description="A fall not yet reported is dropped when no camera has seen the person "
        "lying for this long (seconds; a lying read after so long is no longer that fall).",
    )
    reach_m: float = Field(
        _FALL.reach_m,
        gt=0,
        le=5,
        description="A fall is reported only where the person lies within this of where they "
        "last stood (metres; a track dragged further by a misread box is no fall).",
    )
    handover_m: float = Field(
        _FALL.handover_m,
        ge=0,
        le=5,
        description="A track lying within this of a falling person's track that lost them "
        "takes that fall over (metres; the tracker often loses a falling body; 0: off).",
    )
    beside_m: float = Field(
        _FALL.beside_m,
        ge=0,
        le=5,
        description="One camera's lying read within this of someone two cameras see standing "
        "or sitting is not reported (metres; most often an extra box of that person; 0: off).",
    )
    stayed_m: float = Field(
        _FALL.stayed_m,
        ge=0,
        le=5,
        description="A fall is not reported while someone stands within this of where the "
        "falling track stood (metres; its person is still up, the track drifted off; 0: off).",
    )

    def rules(self) -> FallRules:
        return FallRules(**self.model_dump(exclude={"enabled"}))


class HomeAssistantSettings(BaseModel):
    """Home Assistant MQTT discovery: per zone an occupancy binary_sensor and a count sensor,
    per room a people sensor and a fall binary_sensor."""

    model_config = _STRICT
    discovery: bool = Field(
        False, description="Publish retained discovery configs so Home Assistant adds the room."
    )
    prefix: str = Field(
        "homeassistant", pattern=r"^[A-Za-z0-9_-]+$", description="HA discovery topic prefix."
    )
    device_name: str | None = Field(
        None, max_length=100, description="Device name shown in HA; default 'MoM <room>'."
    )


_TOPIC_LEVEL = re.compile(r"^[^/+#\x00]+$")


class MqttSettings(BaseModel):
    """Publish positions, zone occupancy, events, availability and health to an MQTT broker."""

    model_config = _STRICT
    host: str = Field(min_length=1, description="Broker host name or address.")
    port: int = Field(1883, ge=1, le=65535, description="Broker TCP port (8883 usual for TLS).")
    username: str | None = Field(None, description="User name, if the broker wants one.")
    password: SecretStr | None = Field(None, description="Password for username.")
    tls: bool = Field(False, description="Connect with TLS (server certificate verified).")
    ca_file: Path | None = Field(
        None, description="CA certificate file for TLS; default: the system's CAs."
    )
    base_topic: str = Field(
        "momloc", description="First topic level(s): {base_topic}/{room}/positions, ..."
    )
    room: str = Field(
        "room",
        pattern=NAME_PATTERN,
        description="This daemon's room name (one topic level); one per camera group.",
    )
    rate: float = Field(
        10.0, gt=0, le=100, description="Most position messages per second (newest wins)."
    )
    include_outside: bool = Field(
        False,
        description="Also publish people served flagged outside the set-up area "
        "(tracking.outside_area: flag); by default positions and counts are the inside only.",
    )
    client_id: str | None = Field(
        None, max_length=128, description="MQTT client id; default momloc-{room}-<random>."
    )
    keepalive: int = Field(
        30,
        ge=5,
        le=3600,
        description="Seconds between keep-alives; the broker sends the last "
        "will after 1.5x this without a word (a killed process is noticed at once).",
    )
    health_interval_s: float = Field(
        5.0, gt=0, le=3600, description="Seconds between retained health messages."
    )
    reconnect_min_s: float = Field(
        0.5, gt=0, le=60, description="First reconnect delay; doubles up to reconnect_max_s."
    )
    reconnect_max_s: float = Field(30.0, gt=0, le=3600, description="Longest reconnect delay.")
    max_pending_events: int = Field(
        1000, ge=1, le=100000, description="Events kept while the broker is away (oldest dropped)."
    )
    max_unsent: int = Field(
        8,
        ge=1,
        le=10000,
        description="Messages handed to the socket but not yet written before new positions are "
        "dropped instead (a broker that stops reading cannot grow memory).",
    )
    home_assistant: HomeAssistantSettings = Field(
        default_factory=HomeAssistantSettings, description="Home Assistant MQTT discovery."
    )

    @field_validator("base_topic")
    @classmethod
    def _valid_base(cls, value: str) -> str:
        levels = value.split("/")
        if not value or any(not _TOPIC_LEVEL.match(level) for level in levels):
            raise ValueError(
                "must be topic levels separated by '/', without '+', '#' or empty levels"
            )
        return value

    def topic(self, *levels: str) -> str:
        return "/".join((self.base_topic, self.room, *levels))


class OscSettings(BaseModel):
    """Send every snapshot as one OSC bundle over UDP (TouchDesigner, Max/MSP, Processing, ...).

    Example: ``osc: {host: 127.0.0.1, port: 9000, rate: 30}``; or ``MOMLOC_OSC__PORT=9000``.
    """

    model_config = _STRICT
    host: str = Field("127.0.0.1", min_length=1, description="Receiver host name or address (UDP).")
    port: int = Field(9000, ge=1, le=65535, description="Receiver UDP port.")
    rate: float = Field(
        30.0, gt=0, le=200, description="Most bundles per second (newest snapshot wins)."
    )
