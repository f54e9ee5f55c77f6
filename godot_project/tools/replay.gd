## Replays a trained policy through PunchController itself, many punches at several noise sigmas, and writes
## what each punch did for `punch replay` to analyse (it computes the rewards in Python).
##
## tools/godot --headless --fixed-fps 120 --path godot_project --script res://tools/replay.gd -- \
##     --policy=PATH --sigmas=0.1,0.5 --episodes=100 --out=DIR [--noise-decisions=4] [--characters=64]
##     [--characters-per-world=16] [--seed=0] [--bag=distance_m,height_m,side_m] [--bags=FILE.json]
##     [--start=guard|after_punch] [--idle-frames=0]
##
## `--bags` names a JSON list of placements (`distance_m`, `height_m`, `side_m`, optional
## `velocity_side_mps` and `velocity_forward_mps`: a bag already swinging); episode e uses entry e modulo the
## list's length. `--start=after_punch` starts every recorded punch from the end of an earlier one: each
## controller punches once, then again at once from where that left it, with its bag put back as placed
## (only the second punch is recorded). `--idle-frames=N` keeps each batch's characters standing, their
## controllers idle, for N physics frames after their punches, and records the controllers' work in each.
##
## Characters run side by side like the training server's slots: each group shares a physics world (a
## SubViewport with its own World3D) and two collision layers per character keep them apart. Every batch is
## built fresh, so every punch starts from the same state. Episode e at sigma index s uses noise seed
## seed * 1000003 + s * 100003 + e, whatever the batch size.
##
## Output per sigma index s in DIR: features_s.f32 [episodes, frames, F], observations_s.f32
## [episodes, decisions, 51], mean_actions_s.f32 and actions_s.f32 [episodes, decisions, 10], all little-endian
## float32, and meta.json (with the controllers' inference counts and time, and their work per physics frame,
## punching and, with `--idle-frames`, idle, for `punch bench inference`). Progress lines:
## `REPLAY_PROGRESS done total`.
extends SceneTree

const PunchPair := preload("res://tools/punch_pair.gd")

var _options := {
	"policy": "", "sigmas": "0", "episodes": "10", "out": "", "noise-decisions": "-1", "characters": "64",
	"characters-per-world": "16", "seed": "0", "bag": "", "bags": "", "start": "guard", "idle-frames": "0",
}
var _bags: Array = []
var _sigmas := PackedFloat32Array()
var _sigma_index := 0
var _episodes_done := 0
var _episodes_total := 0
var _arenas: Array[SubViewport] = []
var _controllers: Array[Node] = []
var _pending := 0
var _files := {}
var _meta := {}
var _inference := {"calls": 0, "rows": 0, "usec": 0.0}
var _controller_frame_usec := []
var _idle_frame_usec := []
var _idle_frames_left := -1


func _initialize() -> void:
	var error := PunchPair.read_options(_options, ["policy", "out"])
	if error != "":
		_fail(error)
		return
	_sigmas = PunchPair.floats(_options.sigmas)
	_episodes_total = int(_options.episodes)
	if _episodes_total < 1:
		_fail("--episodes must be at least 1")
		return
	if _options.bags != "":
		var parsed = JSON.parse_string(FileAccess.get_file_as_string(_options.bags))
		if not parsed is Array or (parsed as Array).is_empty():
			_fail("--bags must name a JSON file holding a list of placements: %s" % _options.bags)
			return
		_bags = parsed
	if not _options.start in ["guard", "after_punch"]:
		_fail("--start is guard or after_punch, not '%s'" % _options.start)
		return
	DirAccess.make_dir_recursive_absolute(_options.out)
	_meta = {"policy": _options.policy, "sigmas": Array(_sigmas), "episodes": _episodes_total,
		"noise_decisions": int(_options["noise-decisions"]), "seed": int(_options.seed), "bag": _options.bag,
		"bags": _options.bags, "start": _options.start,
		"characters": int(_options.characters), "characters_per_world": int(_options["characters-per-world"]),
		"feature_names": Array(ClassDB.class_call_static("PunchSpec", "feature_names"))}


func _physics_process(_delta: float) -> bool:
	if _sigma_index >= _sigmas.size():
		return true
	if not _controllers.is_empty():
		if _pending > 0:
			return false
		if _idle_frames_left < 0 and int(_options["idle-frames"]) > 0:
			_controller_frame_usec.append(PunchProbe.take_frame_cost_usec())
			_idle_frames_left = int(_options["idle-frames"]) + 1
			_idle_frame_usec.append([])
		if _idle_frames_left > 0:
			# Frame by frame: a median is not moved by the rare frame the OS takes the thread away.
			_idle_frame_usec[-1].append(PunchProbe.take_frame_cost_usec())
			_idle_frames_left -= 1
			if _idle_frames_left > 0:
				return false
			_idle_frame_usec[-1].pop_front()  # the frame the punches ended in
		_idle_frames_left = -1
		_collect_batch()
	if _sigma_index < _sigmas.size():
		_start_batch()
		return false
	_meta["inference"] = _inference
	_meta["controller_frame_usec_per_batch"] = _controller_frame_usec
	_meta["idle_controller_frame_usec_per_batch"] = _idle_frame_usec
	var meta_file := FileAccess.open(_options.out.path_join("meta.json"), FileAccess.WRITE)
	meta_file.store_string(JSON.stringify(_meta, "  "))
	meta_file.close()
	print("REPLAY_DONE")
	return true


func _start_batch() -> void:
	var count := mini(int(_options.characters), _episodes_total - _episodes_done)
	var per_world := clampi(int(_options["characters-per-world"]), 1, PunchPair.MAX_PER_WORLD)
	# --bag=distance,height,side in metres; by default the placement the policies train at.
	var default_offset := PunchSpec.default_target_offset()
	var bag := PackedFloat64Array([default_offset.z, default_offset.y, default_offset.x])
	if _options.bag != "":
		bag = (_options.bag as String).split_floats(",")
	var arena: SubViewport
	for slot in count:
		if slot % per_world == 0:
			arena = PunchPair.add_arena(root)
			_arenas.append(arena)
		var seed := int(_options.seed) * 1000003 + _sigma_index * 100003 + _episodes_done + slot
		var offset := Vector3(bag[2], bag[1], bag[0])
		var velocity := Vector3.ZERO
		if not _bags.is_empty():
			var entry: Dictionary = _bags[(_episodes_done + slot) % _bags.size()]
			offset = Vector3(entry.side_m, entry.height_m, entry.distance_m)
			velocity = Vector3(entry.get("velocity_side_mps", 0.0), 0.0, entry.get("velocity_forward_mps", 0.0))
		var controller := PunchPair.add(arena, slot % per_world, Vector3.ZERO, offset,
			_options.policy, _sigmas[_sigma_index], int(_options["noise-decisions"]), seed, velocity)
		PunchProbe.set_recording(controller, true)
		controller.set("auto_recover", false)  # each batch's scene is freed after its punches
		var lead_punches := [1 if _options.start == "after_punch" else 0]
		var bag_body: RigidBody3D = controller.get("target")
		var bag_start := [bag_body.global_transform, bag_body.linear_velocity, bag_body.angular_velocity]
		controller.connect("punch_finished", func(metrics: Dictionary):
			if metrics.get("ended") == "error":
				_fail("a punch stopped on an error: %s" % metrics.get("error", "see the error above"))
				return
			if lead_punches[0] > 0:
				lead_punches[0] -= 1
				# The character starts where its earlier punch left it; the bag hangs as placed again.
				bag_body.global_transform = bag_start[0]
				bag_body.linear_velocity = bag_start[1]
				bag_body.angular_velocity = bag_start[2]
				controller.call("punch")
			else:
				_pending -= 1)
		_controllers.append(controller)
	_pending = count
	PunchProbe.take_inference_counts()
	PunchProbe.take_frame_cost_usec()
	for controller in _controllers:
		if not controller.call("punch"):
			_fail("PunchController refused to punch (see the error above)")
			return


func _collect_batch() -> void:
	var counts: Dictionary = PunchProbe.take_inference_counts()
	for key in _inference:
		_inference[key] += counts[key]
	if int(_options["idle-frames"]) == 0:  # else taken before the idle frames
		_controller_frame_usec.append(PunchProbe.take_frame_cost_usec())
	if _episodes_done == 0:
		for kind in ["features", "observations", "mean_actions", "actions"]:
			_files[kind] = FileAccess.open(_options.out.path_join("%s_%d.f32" % [kind, _sigma_index]), FileAccess.WRITE)
	for controller in _controllers:
		var record: Dictionary = PunchProbe.last_punch_record(controller)
		_meta["frames"] = record.frames
		_meta["decisions"] = record.decisions
		for kind in _files:
			_files[kind].store_buffer((record[kind] as PackedFloat32Array).to_byte_array())
	_episodes_done += _controllers.size()
	print("REPLAY_PROGRESS %d %d" % [_sigma_index * _episodes_total + _episodes_done, _sigmas.size() * _episodes_total])
	PunchPair.free_arenas(_arenas)
	_controllers.clear()
	if _episodes_done >= _episodes_total:
		for kind in _files:
			_files[kind].close()
		_files.clear()
		_episodes_done = 0
		_sigma_index += 1


func _fail(message: String) -> void:
	printerr("error: replay: ", message)
	_sigma_index = _sigmas.size() + 1
	quit(2)
