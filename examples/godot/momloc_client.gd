# MoM Localizer client for Godot 3 (3.2 or later): one node per tracked person, moved from the
# daemon's WebSocket stream (WS /v1/stream, snapshot schema version 1). A single drop-in script:
# copy it into your project, it needs nothing beyond Godot's own WebSocketClient.
#
# Usage: add a Spatial node, attach this script, set `url` (and `token` if the daemon has one),
# optionally `person_scene` (a capsule is created otherwise). Persons are children of this node at
# local (x, 0, y) for floor coordinates (x, y) in metres, as in the Unity and browser clients: move,
# rotate or scale this node to place the floor in your scene (1 unit = 1 metre).
#
# Design:
# - Godot's WebSocketClient is polled from _process on the main thread, so there is no thread and
#   no lock: every packet that arrived since the last frame is parsed, and only the newest
#   snapshot is applied (a slow frame skips snapshots instead of queueing them).
# - The token goes in an `Authorization: Bearer` header (connect_to_url's custom_headers, Godot
#   3.2+), so it never appears in a URL or a log line.
# - Reconnects with exponential back-off (0.5 s doubling to max_backoff_seconds, reset after a
#   successful connect). Close code 4401 (token missing or wrong), delivered by the
#   server_close_request signal before connection_closed, stops retrying: token_was_rejected turns
#   true, an error is printed and the signal `token_rejected` is emitted, because retrying with
#   the same token cannot succeed. Call restart() after setting a new token. (The daemon refuses a
#   token after the handshake, so `connected` is emitted once before `token_rejected`.)
# - Messages are parsed with Godot's JSON; unknown keys are ignored, so newer daemons that add
#   fields keep working. A malformed message is skipped with a warning.
# - A person missing from the stream for despawn_seconds is freed; motion is smoothed (exponential
#   approach at rate `smoothing`, frame-rate independent; 0 jumps to each new position).
#
# Not tested inside the Godot editor: the project's tests run this script in Debian's headless
# godot3-server build (3.2.3) against a live daemon (tests/godot/harness.gd). Godot 4 replaced
# WebSocketClient by WebSocketPeer (and Spatial by Node3D): this file is for Godot 3.
extends Spatial

signal connected
signal disconnected(reason)
signal token_rejected
signal person_added(id, node)
signal person_removed(id)

const TOKEN_REJECTED_CLOSE_CODE = 4401
const FIRST_BACKOFF_SECONDS = 0.5

export var url := "ws://127.0.0.1:8765/v1/stream"
export var token := ""
export var person_scene: PackedScene
export var smoothing := 15.0
export var despawn_seconds := 2.0
export var max_backoff_seconds := 10.0
# Hide people below this confidence (coasting tracks fade towards 0).
export var min_confidence := 0.0

# Status, read-only for users of this node.
var online := false  # true while the socket is open
var token_was_rejected := false
var attempts := 0  # connection attempts since _ready / restart()
var last_seq := -1  # seq of the last applied snapshot (restarts at 1 with the daemon)
var last_capture_time := 0.0  # unix seconds of the last applied snapshot: latency = now - this
var last_error := ""  # the last connection problem, "" while all is well
var people := {}  # id (int) -> Spatial, the live node of each person

var _socket: WebSocketClient
var _latest = null  # newest parsed snapshot (Dictionary) not yet applied
var _close_code := -1
var _ended := ""  # why the current attempt ended ("" while it goes on); set by the signals
var _backoff := FIRST_BACKOFF_SECONDS
var _retry_in := -1.0  # seconds until the next attempt; < 0 while connecting or connected
var _clock := 0.0  # seconds since _ready (for despawn)
var _targets := {}  # id -> Vector3
var _last_seen := {}  # id -> _clock when last in a snapshot


func _ready() -> void:
	restart()


# Forget any previous connection and its errors, then connect (also after a rejected token).
func restart() -> void:
	_drop_socket()
	token_was_rejected = false
	attempts = 0
	last_error = ""
	_backoff = FIRST_BACKOFF_SECONDS
	_connect()


# The status at a glance (what a HUD or a test shows).
func status() -> Dictionary:
	return {
		"connected": online,
		"attempts": attempts,
		"rejected": token_was_rejected,
		"error": last_error,
		"seq": last_seq,
	}


func _exit_tree() -> void:
	_drop_socket()


func _connect() -> void:
	_retry_in = -1.0
	_close_code = -1
	_ended = ""
	_socket = WebSocketClient.new()
	_socket.connect("connection_established", self, "_on_established")
	_socket.connect("connection_error", self, "_on_error")
	_socket.connect("connection_closed", self, "_on_closed")
	_socket.connect("server_close_request", self, "_on_close_request")
	_socket.connect("data_received", self, "_on_data")
	var headers := PoolStringArray()
	if token != "":
		headers.append("Authorization: Bearer " + token)
	attempts += 1
	var err: int = _socket.connect_to_url(url, PoolStringArray(), false, headers)
	if err != OK:
		_ended = "cannot connect to %s (error %d)" % [url, err]


# The socket is dropped only from _process, never inside one of its own signals.
func _drop_socket() -> void:
	if _socket != null:
		_socket.disconnect_from_host()
		_socket = null
	online = false


func _on_established(_protocol: String) -> void:
	online = true
	last_error = ""
	_backoff = FIRST_BACKOFF_SECONDS
	print("MoMLocalizerClient: connected to ", url)
	emit_signal("connected")


func _on_close_request(code: int, _reason: String) -> void:
	_close_code = code


func _on_error() -> void:
	_ended = "cannot connect to " + url


func _on_closed(_was_clean: bool) -> void:
	_ended = "connection closed by the daemon"


func _on_data() -> void:
	var peer := _socket.get_peer(1)
	while peer.get_available_packet_count() > 0:
		var text := peer.get_packet().get_string_from_utf8()
		var snapshot = parse_snapshot(text)
		if snapshot == null:
			push_warning("MoMLocalizerClient: bad message skipped")
			continue
		_latest = snapshot


# After an attempt ended: stop on a rejected token, otherwise retry after the back-off.
func _attempt_ended() -> void:
	var was_online := online
	_drop_socket()
	if _close_code == TOKEN_REJECTED_CLOSE_CODE:
		token_was_rejected = true
		last_error = "the daemon rejected the token"
		push_error(
			"MoMLocalizerClient: the daemon rejected the token (close code 4401); "
			+ "set token and call restart()"
		)
		emit_signal("disconnected", last_error)
		emit_signal("token_rejected")
		return
	last_error = _ended
	_retry_in = _backoff
	push_warning("MoMLocalizerClient: %s; retrying in %.1f s" % [_ended, _backoff])
	_backoff = min(_backoff * 2.0, max_backoff_seconds)
	if was_online:
		emit_signal("disconnected", last_error)


# The snapshot in `text` as {seq, t, people: [{id, x, y, vx, vy, confidence}]}, or null.
static func parse_snapshot(text: String):
	var parsed := JSON.parse(text)
	if parsed.error != OK or typeof(parsed.result) != TYPE_DICTIONARY:
		return null
	var root: Dictionary = parsed.result
	var people_in := []
	for item in root.get("people", []):
		if typeof(item) != TYPE_DICTIONARY or not item.has("id"):
			continue
		people_in.append({
			"id": int(item["id"]),
			"x": float(item.get("x", 0.0)),
			"y": float(item.get("y", 0.0)),
			"vx": float(item.get("vx", 0.0)),
			"vy": float(item.get("vy", 0.0)),
			"confidence": float(item.get("confidence", 0.0)),
		})
	return {"seq": int(root.get("seq", 0)), "t": float(root.get("t", 0.0)), "people": people_in}


func _process(delta: float) -> void:
	_clock += delta
	if _socket != null:
		_socket.poll()
		if _ended != "":
			_attempt_ended()
	elif _retry_in >= 0.0:
		_retry_in -= delta
		if _retry_in < 0.0:
			_connect()
	if _latest != null:
		_apply(_latest)
		_latest = null
	_move_and_despawn(delta)


func _apply(snapshot: Dictionary) -> void:
	last_seq = snapshot["seq"]
	last_capture_time = snapshot["t"]
	for person in snapshot["people"]:
		if person["confidence"] < min_confidence:
			continue
		var id: int = person["id"]
		var target := Vector3(person["x"], 0.0, person["y"])
		var node: Spatial = people.get(id)
		if node == null or not is_instance_valid(node):
			node = person_scene.instance() if person_scene != null else _default_person()
			node.name = "person_%d" % id
			add_child(node)
			node.translation = target
			people[id] = node
			emit_signal("person_added", id, node)
		_targets[id] = target
		_last_seen[id] = _clock
		var velocity := Vector3(person["vx"], 0.0, person["vy"])
		if velocity.length_squared() > 0.01:
			# face the walking direction (a node looks along its -Z)
			node.rotation = Vector3(0.0, atan2(-velocity.x, -velocity.z), 0.0)


func _move_and_despawn(delta: float) -> void:
	var follow := 1.0 if smoothing <= 0.0 else 1.0 - exp(-smoothing * delta)
	for id in people.keys():
		var node: Spatial = people[id]
		if not is_instance_valid(node) or _clock - _last_seen[id] > despawn_seconds:
			if is_instance_valid(node):
				node.queue_free()
			people.erase(id)
			_targets.erase(id)
			_last_seen.erase(id)
			emit_signal("person_removed", id)
			continue
		node.translation = node.translation.linear_interpolate(_targets[id], follow)


# An empty root on the floor point with a 1.7 m capsule standing on it. Godot's headless "Server"
# build (a dedicated server, or the project's tests) draws nothing: its dummy renderer keeps no
# meshes and prints an error for each one, so the capsule is left out there.
func _default_person() -> Spatial:
	var root := Spatial.new()
	if OS.has_feature("Server"):
		return root
	var body := MeshInstance.new()
	var capsule := CapsuleMesh.new()
	capsule.radius = 0.25
	capsule.mid_height = 1.2  # total height mid_height + 2 radius = 1.7 m
	body.mesh = capsule
	body.rotation_degrees = Vector3(90.0, 0.0, 0.0)  # Godot 3 capsules lie along Z
	body.translation = Vector3(0.0, 0.85, 0.0)
	root.add_child(body)
	return root
