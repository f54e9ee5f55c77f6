## Any transform a game puts on a punching model: a rig (Mixamo naming, T-pose, an idle animation) driven by
## PunchSkeletonModifier from a PunchController that punches a sandbag with the shipped straight policy
## (--policy=PATH, no noise), while the game scales, mirrors and breaks the transforms of the model's root, its
## skeleton, a bone, the PunchCharacter's parent and the target (a marker on the bag: the bag's own body stays
## whole, as physics needs).
##
## Phases, each on a fresh scene and each opened by a line `CHAOS_PHASE <name>` (the test counts the log lines
## between them): `scale0_start` (the model at scale 0 from the start, then its size back), `scale0_mid` (scaled to
## 0 in the middle of a punch, then back), `skeleton_mirrored` (the skeleton at scale.x -1), `character_mirrored_mid`
## (the character's parent mirrored in the middle of a punch), `rest_nan` (a NaN in the upper arm's rest) and
## `chaos` (--seed=N, --frames=F: every frame, each node gets with some chance one of: its normal transform, scale
## 0, -1 on one axis, non-uniform, 1e6, 1e-8, NaN; a random bone gets a scale or a NaN rotation). A punch is asked
## for at most every 30 frames.
##
## Prints `CHAOS <json>`: per phase its frames, punches asked for (`attempts`), started and finished, the errors the
## finished punches gave, the frames in which the modifier wrote a pose while the model had scale 0
## (`written_degenerate`, scale0 phases) and after it (`written_after`: from then to the phase's end), and its
## `mapping_problem`; then quits 0.
extends SceneTree

const NAMES := ["mixamorig_Hips", "mixamorig_Spine", "mixamorig_Spine1", "mixamorig_Spine2", "mixamorig_Neck",
	"mixamorig_Head"]
const SHOULDER_Y := 1.42
const UPPER_ARM_M := 0.282
const FOREARM_M := 0.269
const HAND_M := 0.068 / 0.75
const PHASES := ["scale0_start", "scale0_mid", "skeleton_mirrored", "character_mirrored_mid", "rest_nan", "chaos"]

var _policy := ""
var _seed := 1
var _chaos_frames := 600
var _rng := RandomNumberGenerator.new()
var _report := {}
var _phases: Array = PHASES.duplicate()
var _phase := ""
var _frame := 0
var _length := 0
var _last_punch := -1000
var _scene: Dictionary = {}
var _entry: Dictionary = {}


func _initialize() -> void:
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--policy="):
			_policy = argument.trim_prefix("--policy=")
		elif argument.begins_with("--seed="):
			_seed = int(argument.trim_prefix("--seed="))
		elif argument.begins_with("--frames="):
			_chaos_frames = int(argument.trim_prefix("--frames="))
		elif argument.begins_with("--phases="):
			_phases = Array(argument.trim_prefix("--phases=").split(","))
	_rng.seed = _seed


func _physics_process(_delta: float) -> bool:
	if _phase == "" or _frame >= _length:
		if _phase != "":
			_end_phase()
		if _phases.is_empty():
			print("CHAOS ", JSON.stringify(_report))
			quit(0)
			return false
		_begin_phase(_phases.pop_front())
		return false
	_step()
	_frame += 1
	return false


func _begin_phase(phase: String) -> void:
	_phase = phase
	_frame = 0
	_last_punch = -1000
	_length = _chaos_frames if phase == "chaos" else 480
	print("CHAOS_PHASE ", phase)
	PunchProbe.take_skeleton_cost_usec()
	_scene = _build_scene(phase == "rest_nan")
	_entry = {"frames": _length, "attempts": 0, "started": 0, "finished": 0, "errors_in_finished": [],
		"written_degenerate": -1, "written_after": -1}
	_scene.controller.connect("punch_started", func(_move, _hand, _combo_index): _entry.started += 1)
	_scene.controller.connect("punch_finished", func(metrics: Dictionary):
		_entry.finished += 1
		if metrics.has("error"):
			_entry.errors_in_finished.append(metrics.error))
	if phase == "scale0_start":
		_scene.rig.scale = Vector3.ZERO
	elif phase == "skeleton_mirrored":
		_scene.skeleton.scale = Vector3(-1, 1, 1)


func _step() -> void:
	var rig: Node3D = _scene.rig
	match _phase:
		"scale0_start":
			if _frame == 240:
				_entry.written_degenerate = PunchProbe.take_skeleton_cost_usec().frames
				rig.scale = Vector3.ONE
		"scale0_mid":
			if _frame == 10:
				PunchProbe.take_skeleton_cost_usec()
				rig.scale = Vector3.ZERO
			if _frame == 240:
				_entry.written_degenerate = PunchProbe.take_skeleton_cost_usec().frames
				rig.scale = Vector3.ONE
		"character_mirrored_mid":
			if _frame == 10:
				_scene.pivot.scale = Vector3(-1, 1, 1)
			if _frame == 240:
				_scene.pivot.scale = Vector3.ONE
		"chaos":
			_chaos()
	if _frame - _last_punch >= 30 and not _scene.controller.call("is_punching"):
		_last_punch = _frame
		_entry.attempts += 1
		_scene.controller.call("punch")


func _chaos() -> void:
	for node in [_scene.rig, _scene.skeleton, _scene.pivot, _scene.target]:
		if _rng.randf() < 0.2:
			node.transform = _random_transform(node == _scene.target)
	var skeleton: Skeleton3D = _scene.skeleton
	if _rng.randf() < 0.2:
		var bone := _rng.randi_range(0, skeleton.get_bone_count() - 1)
		var pick := _rng.randi_range(0, 3)
		if pick == 0:
			skeleton.set_bone_pose_scale(bone, _random_scale())
		elif pick == 1:
			skeleton.set_bone_pose_rotation(bone, Quaternion(NAN, 0, 0, 1))
		elif pick == 2:
			skeleton.set_bone_pose_rotation(bone, Quaternion(0, 0, 0, 0))
		else:
			skeleton.reset_bone_pose(bone)


func _random_scale() -> Vector3:
	match _rng.randi_range(0, 6):
		0:
			return Vector3.ZERO
		1:
			return Vector3(-1, 1, 1)
		2:
			return Vector3(1, 0.01, 3)
		3:
			return Vector3.ONE * 1e6
		4:
			return Vector3.ONE * 1e-8
		5:
			return Vector3(NAN, 1, 1)
	return Vector3.ONE


func _random_transform(is_target: bool) -> Transform3D:
	var origin: Vector3 = _scene.target_home if is_target else Vector3.ZERO
	var pick := _rng.randi_range(0, 3)
	if pick == 1:
		origin = Vector3(NAN, 0, 0)
	elif pick == 2:
		origin *= 1e6
	return Transform3D(Basis.from_scale(_random_scale()), origin)


func _end_phase() -> void:
	_entry["mapping_problem"] = _scene.modifier.call("mapping_problem")
	_entry["written_after"] = PunchProbe.take_skeleton_cost_usec().frames
	_report[_phase] = _entry
	for key in ["rig", "pivot", "bag", "controller"]:
		if is_instance_valid(_scene[key]):
			_scene[key].free()


func _build_scene(nan_rest: bool) -> Dictionary:
	var rig := _build_rig()
	root.add_child(rig)
	var skeleton: Skeleton3D = rig.get_node("Armature/Skeleton3D")
	if nan_rest:
		var arm := skeleton.find_bone("mixamorig_RightArm")
		var rest := skeleton.get_bone_rest(arm)
		rest.origin.x = NAN
		skeleton.set_bone_rest(arm, rest)
	_animate(rig, skeleton)
	# The character under a pivot the game may scale (as an enemy's root node holds both its model and its body).
	var pivot := Node3D.new()
	root.add_child(pivot)
	var character: Node3D = load("res://addons/punch_controller/scenes/punch_character.tscn").instantiate()
	pivot.add_child(character)
	var bag: Node3D = load("res://addons/punch_controller/scenes/punch_sandbag.tscn").instantiate()
	bag.position = PunchSpec.default_target_offset()
	root.add_child(bag)
	var target := Marker3D.new()
	bag.add_child(target)
	var controller: Node = ClassDB.instantiate("PunchController")
	controller.set("character", character)
	controller.set("target", target)
	controller.set("policy", load(_policy))
	root.add_child(controller)
	var modifier: Node = ClassDB.instantiate("PunchSkeletonModifier")
	modifier.set("controller", controller)
	skeleton.add_child(modifier)
	return {"rig": rig, "skeleton": skeleton, "pivot": pivot, "character": character, "bag": bag, "target": target,
		"target_home": target.position, "controller": controller, "modifier": modifier}


## A Mixamo-named rig in a T-pose, each bone's +Y toward its child with a roll, under an "Armature" node.
func _build_rig() -> Node3D:
	var bones: Array = []  # [name, parent index, global position]
	bones.append([NAMES[0], -1, Vector3(0, 1.0, 0)])
	var y := [1.1, 1.22, 1.32]
	for i in 3:
		bones.append([NAMES[1 + i], bones.size() - 1, Vector3(0, y[i], 0)])
	var chest := bones.size() - 1
	bones.append([NAMES[4], chest, Vector3(0, 1.5, 0)])
	bones.append([NAMES[5], bones.size() - 1, Vector3(0, 1.6, 0)])
	for s in 2:
		var sign := 1.0 if s == 0 else -1.0
		var side := "Left" if s == 0 else "Right"
		var out := Vector3(sign, 0, 0)
		var shoulder := Vector3(sign * 0.18, SHOULDER_Y, 0)
		bones.append(["mixamorig_%sShoulder" % side, chest, Vector3(sign * 0.04, 1.4, 0.02)])
		bones.append(["mixamorig_%sArm" % side, bones.size() - 1, shoulder])
		bones.append(["mixamorig_%sForeArm" % side, bones.size() - 1, shoulder + UPPER_ARM_M * out])
		bones.append(["mixamorig_%sHand" % side, bones.size() - 1, shoulder + (UPPER_ARM_M + FOREARM_M) * out])
		bones.append(["mixamorig_%sHandMiddle1" % side, bones.size() - 1,
			shoulder + (UPPER_ARM_M + FOREARM_M + HAND_M) * out])
	for s in 2:
		var sign := 1.0 if s == 0 else -1.0
		var side := "Left" if s == 0 else "Right"
		bones.append(["mixamorig_%sUpLeg" % side, 0, Vector3(sign * 0.1, 0.95, 0)])
		bones.append(["mixamorig_%sLeg" % side, bones.size() - 1, Vector3(sign * 0.1, 0.5, 0)])
		bones.append(["mixamorig_%sFoot" % side, bones.size() - 1, Vector3(sign * 0.1, 0.08, 0.02)])
	var skeleton := Skeleton3D.new()
	skeleton.name = "Skeleton3D"
	var globals: Array[Transform3D] = []
	for i in bones.size():
		var child := -1
		for j in bones.size():
			if bones[j][1] == i:
				child = j
				break
		var toward: Vector3 = (bones[child][2] - bones[i][2]).normalized() if child >= 0 else \
			(bones[i][2] - bones[bones[i][1]][2]).normalized()
		globals.append(Transform3D(Basis(Quaternion(toward, 0.4 + 0.7 * i) * Quaternion(Vector3.UP, toward)), bones[i][2]))
		skeleton.add_bone(bones[i][0])
	for i in bones.size():
		skeleton.set_bone_parent(i, bones[i][1])
		var parent: Transform3D = globals[bones[i][1]] if bones[i][1] >= 0 else Transform3D()
		skeleton.set_bone_rest(i, parent.affine_inverse() * globals[i])
	skeleton.reset_bone_poses()
	var rig := Node3D.new()
	var armature := Node3D.new()
	armature.name = "Armature"
	rig.add_child(armature)
	armature.add_child(skeleton)
	return rig


## An idle: spine and upper arms swing gently about their own X at 1 Hz.
func _animate(rig: Node3D, skeleton: Skeleton3D) -> void:
	var animation := Animation.new()
	animation.length = 1.0
	animation.loop_mode = Animation.LOOP_LINEAR
	for bone in skeleton.get_bone_count():
		var lower := skeleton.get_bone_name(bone).to_lower()
		var amplitude := 3.0 if "spine" in lower else (10.0 if lower.ends_with("arm") else 0.0)
		if amplitude == 0.0:
			continue
		var track := animation.add_track(Animation.TYPE_ROTATION_3D)
		animation.track_set_path(track, NodePath("%s:%s" % [rig.get_path_to(skeleton), skeleton.get_bone_name(bone)]))
		var rest := skeleton.get_bone_rest(bone).basis.get_rotation_quaternion()
		for k in 9:
			var t := k / 8.0
			animation.rotation_track_insert_key(track, t, rest * Quaternion(Vector3.RIGHT, deg_to_rad(amplitude) * sin(TAU * t)))
	var library := AnimationLibrary.new()
	library.add_animation("idle", animation)
	var player := AnimationPlayer.new()
	player.callback_mode_process = AnimationMixer.ANIMATION_CALLBACK_MODE_PROCESS_PHYSICS
	rig.add_child(player)
	player.add_animation_library("", library)
	player.play("idle")
