## What standing characters cost per physics frame, the engine's step included: N characters (no controller
## punching), each in its physics world slot as evaluate.gd builds them, stand for a while, walking or not; the
## median wall time of a whole frame (headless with `--fixed-fps`, frames run back to back: every node's
## `_physics_process`, `PunchCharacter`'s carrying of its pelvis among them, and the physics step) is printed.
## For BENCHMARKS.md ("Punching on the move: cost"), run beside a build without the kinematic pelvis.
##
## tools/godot --headless --fixed-fps 120 --path godot_project --script res://tools/idle_cost.gd -- \
##     [--characters=100] [--frames=240] [--walk-mps=0]
##
## Prints `IDLE_COST {"characters": N, "walk_mps": v, "median_frame_usec": t, "frames": F}`.
extends SceneTree

const PunchPair := preload("res://tools/punch_pair.gd")

var _options := {"characters": "100", "frames": "240", "walk-mps": "0"}
var _holders: Array[Node3D] = []
var _samples: Array[float] = []
var _frame := 0
var _last_usec := 0


func _initialize() -> void:
	var error := PunchPair.read_options(_options)
	if error != "":
		printerr("error: idle_cost: %s" % error)
		quit(2)
		return
	var policy := "res://addons/punch_controller/policies/straight.onnx"
	var arena: SubViewport
	for slot in int(_options.characters):
		if slot % PunchPair.MAX_PER_WORLD == 0:
			arena = PunchPair.add_arena(root)
		var holder := Node3D.new()
		arena.add_child(holder)
		PunchPair.add(holder, slot % PunchPair.MAX_PER_WORLD, Vector3.ZERO, Vector3(0, 1.35, 0.72), policy, 0.0, -1, 0)
		_holders.append(holder)


## Walks every holder (as a game moves a character) and samples the previous frame's physics-process time.
func _physics_process(delta: float) -> bool:
	var walk := float(_options["walk-mps"])
	for holder in _holders:
		holder.position.z += walk * delta
	_frame += 1
	var now := Time.get_ticks_usec()
	if _frame > 30:  # after the scene has settled
		_samples.append(float(now - _last_usec))
	_last_usec = now
	if _frame < 30 + int(_options.frames):
		return false
	_samples.sort()
	var report := {"characters": int(_options.characters), "walk_mps": walk, "frames": _samples.size(),
		"median_frame_usec": snappedf(_samples[_samples.size() / 2], 0.1)}
	print("IDLE_COST ", JSON.stringify(report))
	return true
