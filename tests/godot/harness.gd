# Headless harness: runs examples/godot/momloc_client.gd the way a Godot scene would (a Spatial
# with the script, exported properties set as in the inspector, added to the tree, then one
# _process per frame at 50 fps) and reports on stdout, one line each, for
# tests/e2e/test_godot_client.py:
#
#   EVENT <signal> [argument]  every signal of the client (connected, disconnected, token_rejected)
#   STATE {json}               after each frame that applied a new snapshot: seq, capture time, the
#                              local position of every person node (x, y, z) and how many exist
#   STATUS {json}              twice a second: the client's status() (connected, attempts,
#                              rejected, error, seq)
#
# The client's push_warning / push_error lines go to stderr as Godot prints them.
#
# Usage: godot3-server --no-window -s harness.gd -- CLIENT.gd URL TOKEN SMOOTHING  (TOKEN "-" for
# none). Runs until terminated (Godot 3.2 has no OS.read_string_from_stdin, and File cannot open
# /dev/stdin when it is a pipe, so "quit" on stdin as in the Unity harness is not possible).
extends SceneTree

var client: Spatial
var frame := 0
var reported_seq := -1


func _init() -> void:
	var args := _user_args()
	if args.size() != 4:
		printerr("usage: -s harness.gd -- CLIENT.gd URL TOKEN SMOOTHING")
		quit(2)
		return
	Engine.target_fps = 50
	client = Spatial.new()
	client.name = "momloc"
	client.set_script(load(args[0]))
	client.url = args[1]
	client.token = "" if args[2] == "-" else args[2]
	client.smoothing = float(args[3])
	client.max_backoff_seconds = 2.0
	for signal_name in ["connected", "token_rejected"]:
		client.connect(signal_name, self, "_on_event", [signal_name])
	client.connect("disconnected", self, "_on_disconnected")
	get_root().add_child(client)


# Arguments after "--" (Godot 3.2 has no OS.get_cmdline_user_args).
func _user_args() -> Array:
	var all := Array(OS.get_cmdline_args())
	var at := all.find("--")
	return all.slice(at + 1, all.size() - 1) if at >= 0 and at < all.size() - 1 else []


func _on_event(name: String) -> void:
	print("EVENT ", name)


func _on_disconnected(reason: String) -> void:
	print("EVENT disconnected ", reason)


func _idle(_delta: float) -> bool:
	frame += 1
	if client.last_seq != reported_seq:
		reported_seq = client.last_seq
		_report_state()
	if frame % 25 == 0:
		print("STATUS ", to_json(client.status()))
	return false


func _report_state() -> void:
	var people := {}
	for id in client.people:
		var node: Spatial = client.people[id]
		if is_instance_valid(node):
			var p := node.translation
			people[str(id)] = [p.x, p.y, p.z]
	var objects := 0
	for child in client.get_children():
		if child.name.begins_with("person_") and not child.is_queued_for_deletion():
			objects += 1
	var state := {
		"seq": reported_seq,
		"t": client.last_capture_time,
		"people": people,
		"objects": objects,
	}
	print("STATE ", to_json(state))
