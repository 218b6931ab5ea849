"""The cameras: ``GET /v1/cameras/{k}/snapshot.jpg`` (the newest frame of camera k with boxes
and track ids drawn), ``GET /v1/cameras/{k}/boxes`` (the same boxes and ids as JSON, with the
frame size) and ``POST /v1/alignment/reset`` (accept the cameras where they are now).

Under ``privacy: positions_only`` the snapshot answers 403 naming the setting, and the pages
draw the boxes on an empty background instead (docs/guides/security.md); the preview store then
holds no frame either (``service.pipeline.listeners.Previews``), so the 403 is not the only
guard.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Body, HTTPException, Query
from fastapi import Path as PathParam
from fastapi.responses import Response

from service.api.auth import TokenCheck
from service.api.errors import error_responses
from service.api.request_guard import EmptyBody
from service.api.snapshot_image import CameraBoxes, camera_boxes_of, render_camera_jpeg
from service.api.state import Daemon

NO_IMAGES = (
    "camera images are off: privacy is positions_only (setting privacy, MOMLOC_PRIVACY); "
    "/v1/cameras/{k}/boxes has the boxes"
)
CameraIndex = Annotated[int, PathParam(ge=0, le=8, description="Camera index")]


def cameras_router(daemon: Daemon, token: TokenCheck) -> APIRouter:
    router = APIRouter(dependencies=token.secured)

    def camera_exists(k: int) -> None:
        if k >= daemon.pipeline.num_cameras:
            raise HTTPException(
                404, f"no camera {k}; cameras are 0..{daemon.pipeline.num_cameras - 1}"
            )

    @router.get(
        "/v1/cameras/{k}/snapshot.jpg",
        summary="Newest frame of camera k with boxes and ids",
        response_class=Response,
        responses={
            200: {"content": {"image/jpeg": {}}, "description": "JPEG image"},
            **error_responses(401, 403, 404, 422, 503, plain_route=True),
        },
    )
    def snapshot_jpg(
        k: CameraIndex,
        quality: Annotated[int, Query(ge=10, le=100, description="JPEG quality")] = 75,
        width: Annotated[int | None, Query(ge=32, le=4096, description="Resize width")] = None,
    ) -> Response:
        camera_exists(k)
        if not daemon.images_allowed:
            raise HTTPException(403, NO_IMAGES)
        data = render_camera_jpeg(daemon.pipeline.view(k), quality=quality, width=width)
        if data is None:
            raise HTTPException(503, f"camera {k} has not delivered a frame yet")
        return Response(data, media_type="image/jpeg", headers={"Cache-Control": "no-store"})

    @router.get(
        "/v1/cameras/{k}/boxes",
        responses=error_responses(401, 403, 404, 422),
        summary="Newest boxes of camera k with track ids (no image: privacy mode's preview)",
    )
    def camera_boxes(k: CameraIndex) -> CameraBoxes:
        camera_exists(k)
        return camera_boxes_of(daemon.pipeline.view(k))

    @router.post(
        "/v1/alignment/reset",
        # 400: a body that is not text (invalid UTF-8), which FastAPI refuses before validation
        responses=error_responses(400, 401, 403, 413, 415, 422),
        summary="Accept the cameras where they are now (new references, clears camera-moved)",
    )
    def reset_alignment(body: Annotated[EmptyBody, Body()]) -> dict[str, Any]:
        daemon.pipeline.reset_alignment()
        return {"cameras": [c["alignment"] for c in daemon.camera_states()]}

    return router
