"""Schema of ``model.json``: checked at load so a damaged file is one clear error, not a crash.

Why a schema: the serving runtime reads ``model.json`` by key; a file edited by hand or written by
another tool with a wrong type (``"encoder": "x"``) used to fail deep inside the runtime with an
``AttributeError`` (an HTTP 500 on ``/v1/model/reload``). Validating the whole description first
turns every such problem into one :class:`~common.errors.MomlocError` line naming the key, and the
daemon keeps the model it had.

Only what serving reads is checked, strictly typed (no string-to-number coercion); keys that are
documentation for people (``settings``, ``metrics``, ``demo``, ...) are left alone, so newer
trainers can add keys without breaking older daemons. Shapes that depend on each other (one image
size and one decoder matrix per camera) are checked too.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from common.errors import MomlocError, shorten

_STRICT = ConfigDict(strict=True, extra="ignore")
Number = Annotated[float, Field(allow_inf_nan=False)]
Matrix34 = Annotated[
    list[Annotated[list[Number], Field(min_length=4, max_length=4)]],
    Field(min_length=3, max_length=3),
]

Matrix33 = Annotated[
    list[Annotated[list[Number], Field(min_length=3, max_length=3)]],
    Field(min_length=3, max_length=3),
]


class SamplerSchema(BaseModel):
    model_config = _STRICT
    observation: Literal["bbox", "keypoints"] = "bbox"
    num_points: int = Field(20, ge=1, le=10_000)
    num_estimators: int = Field(12, ge=1, le=10_000)
    distribution: Literal["uniform", "body"] = "uniform"
    draws: int = Field(4, ge=1, le=10_000)
    extent: bool = True
    seed: int = 20240601


class DrawsSchema(BaseModel):
    model_config = _STRICT
    unit: list[Any]
    keys: list[Any]
    frac: list[Any]


class EncoderSchema(BaseModel):
    model_config = _STRICT
    file: str = Field("encoder.onnx", min_length=1, max_length=255, pattern=r"^[^/\\]+$")


class DecoderSchema(BaseModel):
    model_config = _STRICT
    matrices: list[Matrix34]


class FloorPriorSchema(BaseModel):
    model_config = _STRICT
    policy: Literal["mom", "prior", "blend"] = "mom"
    weights: list[Number] | None = None
    prior: dict[str, Any] | None = None


class WorldBoundsSchema(BaseModel):
    """The floor area the training positions cover (metres): the map's default extent."""

    model_config = _STRICT
    xmin: Number
    xmax: Number
    ymin: Number
    ymax: Number

    @model_validator(mode="after")
    def _ordered(self) -> WorldBoundsSchema:
        if self.xmin > self.xmax or self.ymin > self.ymax:
            raise ValueError("world_bounds: min above max")
        return self


class ModelSchema(BaseModel):
    """The keys of ``model.json`` the serving runtime reads."""

    model_config = _STRICT
    format: Literal["mom-model-v1"]
    version: int = Field(ge=1)
    num_cameras: int = Field(ge=1, le=9)
    image_sizes: list[
        Annotated[list[Annotated[int, Field(ge=1, le=16384)]], Field(min_length=2, max_length=2)]
    ]
    observation: Literal["bbox", "keypoints"]
    sampler: SamplerSchema
    draws: DrawsSchema
    encoder: EncoderSchema = Field(default_factory=EncoderSchema)
    decoder: DecoderSchema
    floor_prior: FloorPriorSchema | None = None
    world_bounds: WorldBoundsSchema | None = None  # absent in models trained before 2026-12
    setup_area: dict[str, Any] | None = None  # models.mom.setup_area; absent before 2026-12-03
    # per camera: its image → the model's (models.mom.image_transform); absent: none repaired
    image_transforms: list[Matrix33 | None] | None = None

    @model_validator(mode="after")
    def _one_per_camera(self) -> ModelSchema:
        k = self.num_cameras
        if len(self.image_sizes) != k:
            raise ValueError(f"image_sizes: {len(self.image_sizes)} entries for {k} cameras")
        if len(self.decoder.matrices) != k:
            raise ValueError(f"decoder.matrices: {len(self.decoder.matrices)} for {k} cameras")
        transforms = self.image_transforms
        if transforms is not None and len(transforms) != k:
            raise ValueError(f"image_transforms: {len(transforms)} for {k} cameras")
        for camera, h in enumerate(transforms or []):
            if h is not None and abs(float(np.linalg.det(np.asarray(h)))) < 1e-12:
                raise ValueError(f"image_transforms: camera {camera}'s is not invertible")
        if self.sampler.observation != self.observation:
            raise ValueError("sampler.observation differs from observation")
        return self


def validate_model_json(meta: Any, origin: str) -> ModelSchema:
    """``meta`` checked against :class:`ModelSchema`; the first problem as one MomlocError line."""
    if not isinstance(meta, dict):
        raise MomlocError(f"{origin}: not a MoM model description (mom-model-v1)")
    if meta.get("format") != "mom-model-v1":
        raise MomlocError(f"{origin}: not a MoM model description (mom-model-v1)")
    try:
        return ModelSchema.model_validate(meta)
    except ValidationError as error:
        first = error.errors()[0]
        where = "".join(f"{part}: " for part in [".".join(map(str, first["loc"]))] if part)
        message = first["msg"].removeprefix("Value error, ").split(" or instance of ")[0]
        raise MomlocError(shorten(f"{origin}: {where}{message}", 300)) from None
