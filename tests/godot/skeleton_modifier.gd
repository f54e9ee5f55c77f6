## A game's own rigged characters punching through PunchSkeletonModifier. Rigs are built here at run time (no mesh:
## the skeleton is what is tested) in several namings (Mixamo as glTF import renames it, Unreal, Godot's humanoid
## profile, and bones with meaningless names), rest poses (T and A) and bone axis conventions (each bone's +Y or
## its +X toward its child, with a roll), standing anywhere, turned any way, each playing an idle animation
## that moves spine, arms and legs. Each rig has a twin that plays the same animation with no modifier: what the
## animation alone gives. Each (mapped) rig's modifier drives it from a PunchController punching a sandbag with
## the shipped straight policy (--policy=PATH, no noise). Glb files given with --glb=PATH (repeatable) are loaded
## with GLTFDocument and run alike. The hands close into fists while punching (`fist_curl`) unless --open-hands.
##
## Prints `SKELETON_MODIFIER <json>`: per rig its mapping, warnings, the fist gap (rig fist: the fist centre the
## modifier reads from the rig, `rig_fist_centres`, carried by the hand's pose; simulated: FistR) at the first hit and its largest
## while fully blended, for a rig with a skinned mesh the gap of its skinned hand's centre at the first hit and how far
## its skinned front lies past the simulated fist's front (FistR plus the fist's radius, along the simulated forearm),
## the simulated arms' lengths (sized to the rig) and the rig's own (measured here from its rest, the same way: upper
## arm head to forearm head, forearm head to that fist centre, between the upper arms' heads; the mean of both sides), the
## largest per-frame rotation of each written bone in the blend-in and blend-out windows, of the animation alone and
## of the fully simulated pose, and the legs' largest difference from the twin. The tiny rig's arms (0.6 of the
## simulated ones) are outside the range the simulated arms can be sized to.
##
## With --bench=N (for `punch bench inference`): N copies of the first --glb (else of the mixamo_t_y rig), no twins
## and nothing recorded, each punching its sandbag --bench-punches=P times (3) one after another; prints
## `SKELETON_BENCH <json>`: the rig, its bone count, the bones written, the modifiers' mean time per character-frame
## in which they wrote (`PunchProbe.take_skeleton_cost_usec`) and the controllers' mean work per physics frame
## since the first punch over N (`PunchProbe.take_frame_cost_usec`).
extends SceneTree

## name, naming, arm drop (deg: 0 T-pose), convention ("y" or "x"), arm scale, yaw (deg), position
const RIGS := [
	["mixamo_t_y", "mixamo", 0.0, "y", 1.0, 0.0, Vector3(0, 0, 0)],
	["unreal_a_x", "unreal", 45.0, "x", 1.0, 90.0, Vector3(10, 0, 0)],
	["profile_t_x", "profile", 0.0, "x", 1.0, -150.0, Vector3(20, 0, 5)],
	["mixamo_a_y_long", "mixamo", 40.0, "y", 1.15, 30.0, Vector3(30, 0, 0)],
	["unreal_t_y_short", "unreal", 0.0, "y", 0.85, 0.0, Vector3(40, 0, 0)],
	["profile_a_y_tiny", "profile", 30.0, "y", 0.6, 60.0, Vector3(60, 0, 0)],
	["mixamo_a_x_cm", "mixamo", 35.0, "x", 1.1, -60.0, Vector3(70, 0, 0)],
	["unmapped", "numbered", 0.0, "y", 1.0, 0.0, Vector3(50, 0, 0)],
]
const NAMES := {
	"mixamo": {"hips": "mixamorig_Hips", "spine": ["mixamorig_Spine", "mixamorig_Spine1", "mixamorig_Spine2"],
		"neck": "mixamorig_Neck", "head": "mixamorig_Head",
		"arm": ["mixamorig_%sShoulder", "mixamorig_%sArm", "mixamorig_%sForeArm", "mixamorig_%sHand", "mixamorig_%sHandMiddle1"],
		"leg": ["mixamorig_%sUpLeg", "mixamorig_%sLeg", "mixamorig_%sFoot"], "sides": ["Left", "Right"]},
	"unreal": {"hips": "pelvis", "spine": ["spine_01", "spine_02", "spine_03"], "neck": "neck_01", "head": "head",
		"arm": ["clavicle_%s", "upperarm_%s", "lowerarm_%s", "hand_%s", "middle_01_%s"],
		"leg": ["thigh_%s", "calf_%s", "foot_%s"], "sides": ["l", "r"]},
	"profile": {"hips": "Hips", "spine": ["Spine", "Chest", "UpperChest"], "neck": "Neck", "head": "Head",
		"arm": ["%sShoulder", "%sUpperArm", "%sLowerArm", "%sHand", "%sMiddleProximal"],
		"leg": ["%sUpperLeg", "%sLowerLeg", "%sFoot"], "sides": ["Left", "Right"]},
}
## The simulated body's proportions (the addon's character scene): shoulder joints 0.36 m apart at 1.42 m,
## upper arm 0.282 m, elbow to fist centre 0.337 m (the wrist 0.269 m from the elbow, the fist centre 0.068 m on:
## three quarters of the way to the knuckles).
const SHOULDER_Y := 1.42
## The one character whose modifier keeps `size_head_to_rig` off (its default).
const HEAD_LEFT_AS_IS := "mixamo_155"
const UPPER_ARM_M := 0.282
const FOREARM_M := 0.269
const HAND_M := 0.068 / 0.75
## The simulated fist's radius (the addon's character scene).
const FIST_RADIUS_M := 0.045

var _policy := ""
var _fist_curl := true
var _rigs: Array[Dictionary] = []
var _frames := 0
var _bench := 0
var _bench_punches := 3
var _bench_rig := ""


func _initialize() -> void:
	var glbs: Array[String] = []
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--policy="):
			_policy = argument.trim_prefix("--policy=")
		elif argument.begins_with("--glb="):
			glbs.append(argument.trim_prefix("--glb="))
		elif argument == "--open-hands":
			_fist_curl = false
		elif argument.begins_with("--bench="):
			_bench = int(argument.trim_prefix("--bench="))
		elif argument.begins_with("--bench-punches="):
			_bench_punches = int(argument.trim_prefix("--bench-punches="))
	if _bench > 0:
		_initialize_bench(glbs)
		return
	for spec in RIGS:
		var units := 100.0 if spec[0].ends_with("_cm") else 1.0
		var rig := _build_rig(spec[1], spec[2], spec[3], spec[4], units)
		var twin := _build_rig(spec[1], spec[2], spec[3], spec[4], units)
		_add(spec[0], rig, twin, spec[5], spec[6])
	var index := 0
	for path in glbs:
		var rig := _load_glb(path)
		var twin := _load_glb(path)
		if rig == null or twin == null:
			print("SKELETON_MODIFIER_GLB_FAILED ", path)
			continue
		_add(path.get_file().get_basename(), rig, twin, 0.0, Vector3(-20.0 - 10.0 * index, 0, 0))
		index += 1


func _initialize_bench(glbs: Array[String]) -> void:
	var original: Node3D = _load_glb(glbs[0]) if not glbs.is_empty() else _build_rig("mixamo", 0.0, "y", 1.0, 1.0)
	if original == null:
		print("SKELETON_MODIFIER_GLB_FAILED ", glbs[0])
		quit(1)
		return
	_bench_rig = glbs[0].get_file().get_basename() if not glbs.is_empty() else "mixamo_t_y"
	for i in _bench:
		var rig: Node3D = original if i == 0 else original.duplicate()
		_add(_bench_rig, rig, null, 0.0, Vector3(4.0 * (i % 16), 0, 6.0 * (i / 16)))


func _load_glb(path: String) -> Node3D:
	var document := GLTFDocument.new()
	var state := GLTFState.new()
	if document.append_from_file(path, state) != OK:
		return null
	return document.generate_scene(state) as Node3D


func _add(name: String, rig: Node3D, twin: Node3D, yaw_deg: float, at: Vector3) -> void:
	rig.transform = Transform3D(Basis(Vector3.UP, deg_to_rad(yaw_deg)), at)
	root.add_child(rig)
	var skeleton: Skeleton3D = rig.find_children("*", "Skeleton3D", true, false)[0]
	_animate(rig, skeleton)
	var twin_skeleton: Skeleton3D = null
	if twin != null:
		twin.transform = Transform3D(Basis(Vector3.UP, deg_to_rad(yaw_deg)), at + Vector3(0, 0, 200))
		root.add_child(twin)
		twin_skeleton = twin.find_children("*", "Skeleton3D", true, false)[0]
		_animate(twin, twin_skeleton)
	var character: Node3D = load("res://addons/punch_controller/scenes/punch_character.tscn").instantiate()
	character.position = at + Vector3(0, 0, -3)  # anywhere: the modifier puts it on the rig
	root.add_child(character)
	var controller: Node = ClassDB.instantiate("PunchController")
	controller.set("character", character)
	controller.set("policy", load(_policy))
	root.add_child(controller)
	var modifier: Node = ClassDB.instantiate("PunchSkeletonModifier")
	modifier.set("controller", controller)
	modifier.set("fist_curl", _fist_curl)
	# The head moved to the rig's too, but on one character (to see the default: the simulated head).
	modifier.set("size_head_to_rig", name != HEAD_LEFT_AS_IS)
	skeleton.add_child(modifier)
	var entry := {"name": name, "rig": rig, "skeleton": skeleton, "twin": twin_skeleton, "character": character,
		"controller": controller, "modifier": modifier, "frames": [], "hit_gap_m": -1.0, "hits": 0,
		"hit_pending": false, "skinned_hit_gap_m": -1.0, "skinned_front_m": -1.0,
		"hand_skin": {}}
	controller.connect("hit", func(_impulse, _speed, _position, _body, _push, _hand, _part, _blocked):
		entry.hits += 1
		# The skeleton's pose is the modified one only while it updates: measured at its next update.
		entry.hit_pending = entry.hit_gap_m < 0.0)
	if twin != null:
		skeleton.connect("skeleton_updated", func(): _record(entry))
	_rigs.append(entry)


## Global rest transforms for a humanoid facing +Z (+X its left), arms scaled by `arm_scale`, in a T-pose or
## with arms `drop_deg` below horizontal.
## `units` per metre: a rig in centimetres (100) sits under an Armature node scaled by 0.01, as FBX imports do.
func _build_rig(naming: String, drop_deg: float, convention: String, arm_scale: float, units: float) -> Node3D:
	var bones: Array = []  # [name, parent index, global position]
	var numbered := naming == "numbered"
	if numbered:
		naming = "mixamo"
	var n: Dictionary = NAMES[naming]
	bones.append([n.hips, -1, Vector3(0, 1.0, 0)])
	var y := [1.1, 1.22, 1.32]
	for i in 3:
		bones.append([n.spine[i], bones.size() - 1, Vector3(0, y[i], 0)])
	var chest := bones.size() - 1
	bones.append([n.neck, chest, Vector3(0, 1.5, 0)])
	bones.append([n.head, bones.size() - 1, Vector3(0, 1.6, 0)])
	var drop := deg_to_rad(drop_deg)
	for s in 2:
		var sign := 1.0 if s == 0 else -1.0
		var side: String = n.sides[s]
		var out := Vector3(sign * cos(drop), -sin(drop), 0)
		var shoulder := Vector3(sign * 0.18, SHOULDER_Y, 0)
		bones.append([n.arm[0] % side, chest, Vector3(sign * 0.04, 1.4, 0.02)])
		bones.append([n.arm[1] % side, bones.size() - 1, shoulder])
		bones.append([n.arm[2] % side, bones.size() - 1, shoulder + UPPER_ARM_M * arm_scale * out])
		bones.append([n.arm[3] % side, bones.size() - 1, shoulder + (UPPER_ARM_M + FOREARM_M) * arm_scale * out])
		bones.append([n.arm[4] % side, bones.size() - 1, shoulder + (UPPER_ARM_M + FOREARM_M + HAND_M) * arm_scale * out])
	for s in 2:
		var sign := 1.0 if s == 0 else -1.0
		var side: String = n.sides[s]
		bones.append([n.leg[0] % side, 0, Vector3(sign * 0.1, 0.95, 0)])
		bones.append([n.leg[1] % side, bones.size() - 1, Vector3(sign * 0.1, 0.5, 0)])
		bones.append([n.leg[2] % side, bones.size() - 1, Vector3(sign * 0.1, 0.08, 0.02)])
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
		var axis := Vector3.UP if convention == "y" else Vector3.RIGHT
		var basis := Basis(Quaternion(toward, 0.4 + 0.7 * i) * Quaternion(axis, toward))
		globals.append(Transform3D(basis, units * bones[i][2]))
		skeleton.add_bone(("Bone%d" % i) if numbered else bones[i][0])
	for i in bones.size():
		skeleton.set_bone_parent(i, bones[i][1])
		var parent: Transform3D = globals[bones[i][1]] if bones[i][1] >= 0 else Transform3D()
		skeleton.set_bone_rest(i, parent.affine_inverse() * globals[i])
	skeleton.reset_bone_poses()
	var rig := Node3D.new()
	var armature := Node3D.new()
	armature.name = "Armature"
	armature.scale = Vector3.ONE / units
	rig.add_child(armature)
	armature.add_child(skeleton)
	return rig


## An idle: spine, upper arms and legs swing gently about their own X (3, 10 and 15 degrees) at 1 Hz.
func _animate(rig: Node3D, skeleton: Skeleton3D) -> void:
	var animation := Animation.new()
	animation.length = 1.0
	animation.loop_mode = Animation.LOOP_LINEAR
	for bone in skeleton.get_bone_count():
		var name := skeleton.get_bone_name(bone)
		var lower := name.to_lower()
		var amplitude := 0.0
		if "spine" in lower or "chest" in lower:
			amplitude = 3.0
		elif lower.ends_with("arm") or "upperarm" in lower:
			amplitude = 10.0
		elif "leg" in lower or "thigh" in lower or "calf" in lower:
			amplitude = 15.0
		if amplitude == 0.0:
			continue
		var track := animation.add_track(Animation.TYPE_ROTATION_3D)
		animation.track_set_path(track, NodePath("%s:%s" % [rig.get_path_to(skeleton), name]))
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


## The visible right fist now (global), for a rig with a skinned mesh: the centre of the skin bound mostly to the
## right hand and the bones below it (palm and fingers), skinned on the CPU with Godot's formula (weighted bone
## global pose * bind pose); INF for a rig without a skin.
func _skinned_fist(entry: Dictionary) -> Vector3:
	var skeleton: Skeleton3D = entry.skeleton
	if entry.hand_skin.is_empty():
		entry.hand_skin = _hand_skin(entry)
	var hand_skin: Dictionary = entry.hand_skin
	if not hand_skin.has("vertices"):
		return Vector3.INF
	var skin: Skin = hand_skin.skin
	var matrices: Array[Transform3D] = []
	for bind in skin.get_bind_count():
		matrices.append(skeleton.get_bone_global_pose(hand_skin.bind_bones[bind]) * skin.get_bind_pose(bind))
	var per_vertex: int = hand_skin.per_vertex
	var vertices: PackedVector3Array = hand_skin.vertices
	var bones: PackedInt32Array = hand_skin.bones
	var weights: PackedFloat32Array = hand_skin.weights
	var centre := Vector3.ZERO
	# The front: the furthest skinned point along the simulated forearm (elbow side to fist), past FistR.
	var fist: Node3D = entry.character.get_node("ForearmR/FistR")
	var along: Vector3 = (fist.global_position - entry.character.get_node("ForearmR").global_position).normalized()
	var front := -INF
	for i in vertices.size():
		var sum := Vector3.ZERO
		for k in per_vertex:
			var w := weights[i * per_vertex + k]
			if w > 0.0:
				sum += w * (matrices[bones[i * per_vertex + k]] * vertices[i])
		centre += sum
		front = maxf(front, (skeleton.global_transform * sum - fist.global_position).dot(along))
	hand_skin.front = front
	return skeleton.global_transform * (centre / vertices.size())


## The vertices of the rig's skinned mesh bound at least half to the right hand and the bones below it, with
## their bones and weights; {} for a rig without a skinned mesh.
func _hand_skin(entry: Dictionary) -> Dictionary:
	var skeleton: Skeleton3D = entry.skeleton
	var hand := skeleton.find_bone(entry.modifier.get("bone_map").get("hand_r", ""))
	var meshes: Array = entry.rig.find_children("*", "MeshInstance3D", true, false)
	if hand < 0 or meshes.is_empty() or meshes[0].skin == null:
		return {"none": true}
	var mesh_instance: MeshInstance3D = meshes[0]
	var skin := mesh_instance.skin
	var arrays := mesh_instance.mesh.surface_get_arrays(0)
	var all_vertices: PackedVector3Array = arrays[Mesh.ARRAY_VERTEX]
	var all_bones: PackedInt32Array = arrays[Mesh.ARRAY_BONES]
	var all_weights: PackedFloat32Array = arrays[Mesh.ARRAY_WEIGHTS]
	var per_vertex := all_bones.size() / all_vertices.size()
	var bind_bones := []
	var in_hand := []
	for bind in skin.get_bind_count():
		var bone := skin.get_bind_bone(bind)
		bone = bone if bone >= 0 else skeleton.find_bone(skin.get_bind_name(bind))
		bind_bones.append(bone)
		var ancestor := bone
		while ancestor >= 0 and ancestor != hand:
			ancestor = skeleton.get_bone_parent(ancestor)
		in_hand.append(ancestor == hand)
	var found := {"skin": skin, "bind_bones": bind_bones, "per_vertex": per_vertex, "vertices": PackedVector3Array(),
		"bones": PackedInt32Array(), "weights": PackedFloat32Array()}
	for i in all_vertices.size():
		var share := 0.0
		for k in per_vertex:
			if in_hand[all_bones[i * per_vertex + k]]:
				share += all_weights[i * per_vertex + k]
		if share >= 0.5:
			found.vertices.append(all_vertices[i])
			for k in per_vertex:
				found.bones.append(all_bones[i * per_vertex + k])
				found.weights.append(all_weights[i * per_vertex + k])
	if found.vertices.is_empty():
		return {"none": true}
	return found


## The rig's right fist now (global): the fist centre the modifier reads from the rig at rest
## (`rig_fist_centres`: from the hand's bones, moved across the hand by its skin), carried by the right hand's pose.
func _hand_fist(skeleton: Skeleton3D, modifier: Node) -> Vector3:
	var hand := skeleton.find_bone(modifier.get("bone_map").get("hand_r", ""))
	var centres: PackedVector3Array = modifier.call("rig_fist_centres")
	if hand < 0 or centres.is_empty():
		return Vector3.INF
	var rest_to_now := skeleton.get_bone_global_pose(hand) * skeleton.get_bone_global_rest(hand).affine_inverse()
	return skeleton.global_transform * (rest_to_now * centres[0])


## The rig's arm lengths at rest, m: [upper arm, forearm to the fist centre, shoulder width].
func _rig_arm_lengths(skeleton: Skeleton3D, modifier: Node) -> Array:
	var bone_map: Dictionary = modifier.get("bone_map")
	var centres: PackedVector3Array = modifier.call("rig_fist_centres")
	var at := func(role: String) -> Vector3:
		return skeleton.get_bone_global_rest(skeleton.find_bone(bone_map[role])).origin
	var scale := skeleton.global_transform.basis.get_scale().y
	var upper := 0.0
	var fore := 0.0
	for side in 2:
		var suffix: String = ["r", "l"][side]
		upper += 0.5 * at.call("upper_arm_" + suffix).distance_to(at.call("forearm_" + suffix))
		fore += 0.5 * at.call("forearm_" + suffix).distance_to(centres[side])
	var width: float = at.call("upper_arm_r").distance_to(at.call("upper_arm_l"))
	return [scale * upper, scale * fore, scale * width]


func _fist_gap(entry: Dictionary) -> float:
	var fist: Node3D = entry.character.get_node("ForearmR/FistR")
	return _hand_fist(entry.skeleton, entry.modifier).distance_to(fist.global_position)


func _record(entry: Dictionary) -> void:
	var skeleton: Skeleton3D = entry.skeleton
	var twin: Skeleton3D = entry.twin
	var rotations := []
	var twin_rotations := []
	var locals := []
	var twin_locals := []
	for bone in skeleton.get_bone_count():
		rotations.append(skeleton.get_bone_global_pose(bone).basis.get_rotation_quaternion())
		twin_rotations.append(twin.get_bone_global_pose(bone).basis.get_rotation_quaternion())
		locals.append(skeleton.get_bone_pose_rotation(bone))
		twin_locals.append(twin.get_bone_pose_rotation(bone))
	entry.frames.append({"weight": entry.modifier.call("blend_weight"), "rotations": rotations, "twin": twin_rotations,
		"locals": locals, "twin_locals": twin_locals, "gap": _fist_gap(entry)})
	if entry.hit_pending:
		entry.hit_gap_m = _fist_gap(entry)
		var skinned := _skinned_fist(entry)
		if skinned != Vector3.INF:
			var fist: Node3D = entry.character.get_node("ForearmR/FistR")
			entry.skinned_hit_gap_m = skinned.distance_to(fist.global_position)
			entry.skinned_front_m = entry.hand_skin.front - FIST_RADIUS_M
		entry.hit_pending = false


## The angle between two rotations, precise near zero (unlike `angle_to`'s acos in single precision).
func _angle(a: Quaternion, b: Quaternion) -> float:
	var d := a.inverse() * b
	return 2.0 * atan2(Vector3(d.x, d.y, d.z).length(), absf(d.w))


func _physics_process(_delta: float) -> bool:
	_frames += 1
	if _frames == 4:
		for entry in _rigs:
			if not entry.modifier.call("is_mapped"):
				continue
			# The sandbag in front of the simulated character, now standing on the rig.
			var character: Node3D = entry.character
			var sandbag: Node3D = load("res://addons/punch_controller/scenes/punch_sandbag.tscn").instantiate()
			sandbag.transform = Transform3D(character.global_transform.basis, character.global_transform * PunchSpec.default_target_offset())
			root.add_child(sandbag)
			entry.controller.set("target", sandbag.get_node("Bag"))
	if _frames == 8:
		for entry in _rigs:
			if entry.modifier.call("is_mapped"):
				entry.controller.call("punch")
		if _bench > 0:
			PunchProbe.take_skeleton_cost_usec()
			PunchProbe.take_frame_cost_usec()
	if _bench > 0:
		if _frames > 8:
			_bench_frame()
		return false
	if _frames == 230:
		var report := []
		for entry in _rigs:
			report.append(_summary(entry))
		print("SKELETON_MODIFIER_COST ", JSON.stringify(PunchProbe.take_skeleton_cost_usec()))
		print("SKELETON_MODIFIER ", JSON.stringify(report))
		quit(0)
	return false


## Punches again every character that is over its punch; once each has punched `_bench_punches` times and is over
## it, prints SKELETON_BENCH and quits (or after 400 frames a punch, saying how many punches were done).
func _bench_frame() -> void:
	var done := 0
	for entry in _rigs:
		var controller: Node = entry.controller
		var busy: bool = controller.call("is_punching") or controller.call("is_recovering")
		if busy:
			continue
		entry.punches = entry.get("punches", 1)
		if entry.punches < _bench_punches:
			controller.call("punch")
			entry.punches += 1
		else:
			done += 1
	if done < _rigs.size() and _frames < 8 + 400 * _bench_punches:
		return
	var cost: Dictionary = PunchProbe.take_skeleton_cost_usec()
	var skeleton: Skeleton3D = _rigs[0].skeleton
	var punches := 0
	for entry in _rigs:
		punches += entry.get("punches", 1)
	# The controllers' mean work per physics frame since the first punch, all of them together.
	var controller_usec: float = PunchProbe.take_frame_cost_usec()
	print("SKELETON_BENCH ", JSON.stringify({"rig": _bench_rig, "characters": _rigs.size(),
		"bones": skeleton.get_bone_count(), "written": PunchProbe.written_bones(_rigs[0].modifier).size(),
		"punches": punches, "character_frames": cost.frames,
		"skeleton_usec_per_character_frame": cost.usec_per_frame,
		"controller_usec_per_character_frame": controller_usec / _rigs.size()}))
	quit(0)


func _summary(entry: Dictionary) -> Dictionary:
	var skeleton: Skeleton3D = entry.skeleton
	var modifier: Node = entry.modifier
	var written: PackedStringArray = PunchProbe.written_bones(modifier)
	var written_ids: Array[int] = []
	for name in written:
		written_ids.append(skeleton.find_bone(name))
	var frames: Array = entry.frames
	var jumps := {"blend_in": 0.0, "blend_out": 0.0, "animation": 0.0, "simulated": 0.0}
	var worst_bone := {}
	var max_gap_full := 0.0
	var pose_gap := 0.0  # largest angle between a written bone's simulated and animated pose
	var gaps := []
	var untouched := 0.0  # largest difference of a bone never written from its twin's (local rotations)
	for f in range(1, frames.size()):
		var before: Dictionary = frames[f - 1]
		var now: Dictionary = frames[f]
		var blending: bool = (now.weight > 0.0 and now.weight < 1.0) or (before.weight > 0.0 and before.weight < 1.0)
		var rising: bool = now.weight >= before.weight
		for bone in skeleton.get_bone_count():
			if bone in written_ids:
				continue
			untouched = max(untouched, _angle(now.locals[bone], now.twin_locals[bone]))
		if now.weight == 1.0:
			max_gap_full = max(max_gap_full, now.gap)
			gaps.append(snappedf(now.gap, 0.001))
		for bone in written_ids:
			var step: float = _angle(now.rotations[bone], before.rotations[bone])
			var anim_step: float = _angle(now.twin[bone], before.twin[bone])
			if now.weight == 1.0:
				pose_gap = max(pose_gap, _angle(now.rotations[bone], now.twin[bone]))
			jumps.animation = max(jumps.animation, anim_step)
			if blending:
				var key := "blend_in" if rising else "blend_out"
				if step > jumps[key]:
					jumps[key] = step
					worst_bone[key] = skeleton.get_bone_name(bone)
			elif now.weight == 1.0 and before.weight == 1.0:
				jumps.simulated = max(jumps.simulated, step)
	var blend_frames := 0
	for f in frames:
		if f.weight > 0.0 and f.weight < 1.0:
			blend_frames += 1
	return {"name": entry.name, "mapped": modifier.call("is_mapped"), "bone_map": modifier.get("bone_map"),
		"written": written, "warnings": Array(modifier.call("configuration_warnings")),
		"problem": modifier.call("mapping_problem"), "hits": entry.hits, "hit_gap_m": entry.hit_gap_m,
		"skinned_hit_gap_m": entry.skinned_hit_gap_m, "skinned_front_m": entry.skinned_front_m,
		"max_gap_full_m": max_gap_full, "jumps_rad": jumps, "worst_bone": worst_bone, "blend_frames": blend_frames,
		"untouched_max_rad": untouched, "frames": frames.size(), "pose_gap_rad": pose_gap, "gaps": gaps,
		"arm_lengths_m": _array(entry.character.call("arm_lengths")),
		"rig_arm_lengths_m": _rig_arm_lengths(skeleton, modifier) if modifier.call("is_mapped") else [],
		"crown_m": entry.character.call("shoulder_to_crown_m"),
		"rig_crown_m": _rig_crown(skeleton, modifier, entry.rig) if modifier.call("is_mapped") else -1.0}


## How high the rig's crown stands above the middle of its upper arms' heads at rest, m: the top of its skinned
## mesh's bounds (the whole body's, standing: the crown), read apart from the modifier's head skin; -1 without a mesh.
func _rig_crown(skeleton: Skeleton3D, modifier: Node, rig: Node3D) -> float:
	var meshes: Array = rig.find_children("*", "MeshInstance3D", true, false)
	if meshes.is_empty() or meshes[0].skin == null:
		return -1.0
	var mesh_instance: MeshInstance3D = meshes[0]
	var top: float = (mesh_instance.global_transform * mesh_instance.get_aabb().end).y
	var bone_map: Dictionary = modifier.get("bone_map")
	var shoulders := Vector3.ZERO
	for role in ["upper_arm_r", "upper_arm_l"]:
		shoulders += 0.5 * (skeleton.global_transform * skeleton.get_bone_global_rest(skeleton.find_bone(bone_map[role]))).origin
	return top - shoulders.y


func _array(v: Vector3) -> Array:
	return [v.x, v.y, v.z]
