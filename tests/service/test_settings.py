"""Settings: YAML + environment precedence, unknown keys rejected, one line per invalid field."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from common.errors import MomlocError
from service.settings import Settings, SyntheticCamera, V4l2Camera, load_settings


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "momloc.yaml"
    path.write_text(text)
    return path


def test_yaml_with_defaults(tmp_path, monkeypatch):
    monkeypatch.delenv("MOMLOC_PORT", raising=False)
    path = write(
        tmp_path,
        "cameras:\n  - {type: v4l2, device: /dev/video0}\n  - {type: synthetic, index: 1}\n"
        "token: s3cret\n",
    )
    with pytest.raises(MomlocError, match="cannot be mixed"):
        from service.pipeline.build import build_rig

        build_rig(load_settings(path))
    settings = load_settings(path)
    assert isinstance(settings.cameras[0], V4l2Camera)
    assert isinstance(settings.cameras[1], SyntheticCamera)
    assert settings.host == "127.0.0.1" and settings.port == 8765
    assert settings.token_value() == "s3cret"
    assert "s3cret" not in repr(settings)


def test_environment_overrides_yaml_and_cli_overrides_both(tmp_path, monkeypatch):
    path = write(tmp_path, "cameras: [{type: synthetic, index: 0}]\nport: 9000\n")
    monkeypatch.setenv("MOMLOC_PORT", "9100")
    monkeypatch.setenv("MOMLOC_DETECTOR__SCORE_THRESHOLD", "0.55")
    monkeypatch.setenv("MOMLOC_KEYPOINT_TESTS", "1")  # unrelated MOMLOC_ variables are ignored
    settings = load_settings(path)
    assert settings.port == 9100
    assert settings.detector.score_threshold == pytest.approx(0.55)
    assert load_settings(path, port=9200, host=None).port == 9200


def test_every_invalid_field_gets_one_line(tmp_path, monkeypatch):
    monkeypatch.delenv("MOMLOC_PORT", raising=False)
    path = write(
        tmp_path,
        "cameras:\n  - {type: v4l2, device: /dev/video0, width: 5}\n"
        "  - {type: file, path: a.mp4, colour: red}\nport: 70000\nnonsense: 1\n"
        "floor: {xmin: 3, xmax: 1, ymin: 0, ymax: 2}\n",
    )
    with pytest.raises(MomlocError) as info:
        load_settings(path)
    lines = str(info.value).splitlines()
    assert len(lines) == 5, lines
    assert all(line.startswith(f"{path}: ") for line in lines)
    text = "\n".join(lines)
    for field in ("cameras.0.width", "cameras.1.colour", "port", "nonsense", "floor"):
        assert f": {field}: " in text


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("cameras: []\n", "cameras: List should have at least 1 item"),
        ("cameras: [{type: webcam, device: x}]\n", "cameras.0"),
        ("port: [1\n", "not valid YAML at line"),
        ("- 1\n- 2\n", "top level must be a mapping"),
        (
            "cameras: [{type: synthetic, index: 0}, {type: synthetic, index: 0}]\n",
            "index appears twice",
        ),
    ],
)
def test_bad_files(tmp_path, text, needle):
    with pytest.raises(MomlocError, match=needle):
        load_settings(write(tmp_path, text))


def test_missing_file(tmp_path):
    with pytest.raises(MomlocError, match="cannot read settings file"):
        load_settings(tmp_path / "nope.yaml")


def test_every_field_is_documented():
    def walk(schema: dict, defs: dict, seen: set[str]) -> list[str]:
        missing = []
        for name, prop in schema.get("properties", {}).items():
            if "description" not in prop:
                missing.append(name)
        for ref_name, sub in defs.items():
            if ref_name not in seen:
                seen.add(ref_name)
                missing += walk(sub, {}, seen)
        return missing

    schema = Settings.model_json_schema()
    assert walk(schema, schema.get("$defs", {}), set()) == []


def test_serve_cli_prints_lines_and_exits_2(tmp_path):
    path = write(tmp_path, "cameras: [{type: v4l2, device: /dev/video0}]\nport: 0\nbogus: 2\n")
    result = subprocess.run(
        [sys.executable, "-m", "service.cli", "serve", "--config", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert f"{path}: port: " in result.stderr
    assert f"{path}: bogus: Extra inputs are not permitted" in result.stderr


@pytest.mark.parametrize(
    ("model_dir", "needle"),
    [
        ("x" * 300, "model_dir: path too long"),
        ("/".join(["d" * 200] * 15), "not a model directory"),  # fits the OS, does not exist
    ],
)
def test_serve_with_an_overlong_model_dir_is_one_line_exit_2(tmp_path, model_dir, needle):
    """Issue 12, defect 2: `File name too long` was a traceback and exit 1."""
    config = f"cameras: [{{type: synthetic, index: 0}}]\nmodel_dir: {model_dir}\n"
    path = write(tmp_path, config)
    result = subprocess.run(
        [sys.executable, "-m", "service.cli", "serve", "--config", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr and needle in result.stderr, result.stderr
    assert len(result.stderr) < 600  # the path is not echoed whole


def test_allowed_origins_and_hosts_are_validated(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    ok = load_settings(
        write(
            tmp_path,
            "cameras: [{type: synthetic, index: 0}]\n"
            "allowed_origins: ['http://localhost:3000', '*']\nallowed_hosts: [tracker.lan]\n",
        )
    )
    assert ok.allowed_origins == ["http://localhost:3000", "*"]
    assert ok.allowed_hosts == ["tracker.lan"]
    bad = "cameras: [{type: synthetic, index: 0}]\nallowed_origins: ['evil.example/x']\n"
    with pytest.raises(MomlocError, match=r"allowed_origins\.0: String should match pattern"):
        load_settings(write(tmp_path, bad))


def test_privacy_from_yaml_and_environment(tmp_path, monkeypatch):
    path = write(tmp_path, "cameras: [{type: v4l2, device: /dev/video0}]\n")
    assert load_settings(path).privacy == "off"
    monkeypatch.setenv("MOMLOC_PRIVACY", "positions_only")
    assert load_settings(path).privacy == "positions_only"
    monkeypatch.setenv("MOMLOC_PRIVACY", "blurred")
    with pytest.raises(MomlocError, match=r"privacy: Input should be 'off' or 'positions_only'"):
        load_settings(path)


def test_record_refuses_in_privacy_mode_one_line_exit_2(tmp_path):
    """No video is recorded, no folder made, no camera opened."""
    path = write(
        tmp_path, "cameras: [{type: v4l2, device: /dev/video0}]\nprivacy: positions_only\n"
    )
    out = tmp_path / "rec"
    result = subprocess.run(
        [sys.executable, "-m", "service.cli", "record", "--config", str(path), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "privacy is positions_only" in lines[0], result.stderr
    assert "MOMLOC_PRIVACY" in lines[0] and not out.exists()


def test_keypoint_back_end_is_a_typed_detector_setting(tmp_path, monkeypatch):
    monkeypatch.delenv("MOMLOC_PORT", raising=False)
    cameras = "cameras: [{type: synthetic, index: 0}]\n"
    path = write(
        tmp_path,
        cameras + "detector: {kind: nanodet, keypoints: true, keypoint_backend: mediapipe}\n",
    )
    settings = load_settings(path)
    assert settings.detector.keypoints and settings.detector.keypoint_backend == "mediapipe"
    assert load_settings(write(tmp_path, cameras)).detector.keypoint_backend == "blazepose"
    with pytest.raises(MomlocError) as info:
        load_settings(
            write(tmp_path, cameras + "detector: {kind: nanodet, keypoint_backend: openpose}\n")
        )
    (line,) = str(info.value).splitlines()
    assert ": detector.keypoint_backend: " in line and "blazepose" in line
