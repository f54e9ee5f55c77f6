## The addon's character moved as a game moves it: its parent node (a stand-in for a CharacterBody3D, with a
## target post riding along) walks at --speed=M/S (default 1.4) along its own +Z while it turns at --turn=DEG/S
## (default 120) every physics frame, from the start; with --policy=PATH it punches (at frame --punch-at=N,
## default 30). Then the parent is moved 5 m and turned 90 degrees in one frame (a teleport). Measures, per
## physics frame, read before the parent moves again (after the step):
## - each body's displacement, its largest, and how far it moved beyond what its velocity explains (a body
##   teleported by Godot's transform propagation moves without the velocity);
## - the pelvis's physics pose against the root's (the character's global transform times the pelvis's rest
##   offset), and its velocity against its displacement times the physics rate (how Jolt moves a kinematic body
##   whose transform is set each frame);
## - the joints' gap (the largest distance between the two bodies' anchors of a joint), as the core measures it;
## - after the teleport, how far each body is from its pose before it, carried with the root.
## Prints `MOVING_CHARACTER <json>`, then quits.
extends SceneTree

const BODIES := ["Pelvis", "Torso", "UpperArmR", "ForearmR", "UpperArmL", "ForearmL"]
const JOINTS := [["Waist", "Pelvis", "Torso"], ["ShoulderR", "Torso", "UpperArmR"], ["ElbowR", "UpperArmR", "ForearmR"],
	["ShoulderL", "Torso", "UpperArmL"], ["ElbowL", "UpperArmL", "ForearmL"]]
const MOVING_FRAMES := 150
const TELEPORT := Vector3(5.0, 0.0, -2.0)

var _speed := 1.4
var _turn := deg_to_rad(120.0)
var _punch_at := 30
var _mover := Node3D.new()
var _character: Node3D
var _controller: Node
var _frames := 0
var _pelvis_rest: Transform3D
var _anchors := []  # per joint: [anchor in the parent body, anchor in the child body]
var _last := {}  # body -> global transform at the last frame
var _before_teleport := {}  # body -> transform relative to the root before the teleport
var _report := {
	"max_step_m": {}, "max_unexplained_m": {}, "max_pelvis_error_m": 0.0, "max_pelvis_turn_error_rad": 0.0,
	"max_pelvis_velocity_error_mps": 0.0, "pelvis_speed_mps": 0.0, "pelvis_spin_radps": 0.0, "max_joint_gap_m": 0.0,
	"punch_started": false, "punched": false, "started": 0, "finished": [], "hits": 0, "teleport_pose_error_m": {},
	"teleport_pelvis_error_m": -1.0, "teleport_max_speed_mps": -1.0,
}


func _initialize() -> void:
	var policy := ""
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--policy="):
			policy = argument.trim_prefix("--policy=")
		elif argument.begins_with("--speed="):
			_speed = float(argument.trim_prefix("--speed="))
		elif argument.begins_with("--turn="):
			_turn = deg_to_rad(float(argument.trim_prefix("--turn=")))
		elif argument.begins_with("--punch-at="):
			_punch_at = int(argument.trim_prefix("--punch-at="))
	_mover.name = "Mover"
	root.add_child(_mover)
	_character = load("res://addons/punch_controller/scenes/punch_character.tscn").instantiate()
	_mover.add_child(_character)
	_controller = ClassDB.instantiate("PunchController")
	_controller.set("character", _character)
	_controller.set("target", _target())
	PunchProbe.set_recording(_controller, true)
	if policy != "":
		_controller.set("policy", load(policy))
	root.add_child(_controller)
	_controller.connect("punch_started", func(_move, _hand, _combo_index): _report.started += 1)
	_controller.connect("hit", func(_impulse, _hit_speed, _position, _body, _push, _hand, _part, _blocked): _report.hits += 1)
	_controller.connect("punch_finished", func(metrics: Dictionary):
		var record: Dictionary = PunchProbe.last_punch_record(_controller)
		var gap_column: int = Array(PunchSpec.feature_names()).find("joint_gap_max_m")
		var features: PackedFloat32Array = record.features
		var count: int = PunchSpec.feature_names().size()
		var gap := 0.0
		for frame in features.size() / count:
			gap = maxf(gap, features[frame * count + gap_column])
		metrics["max_joint_gap_feature_m"] = gap
		_report.finished.append(metrics))
	for name in BODIES:
		_report.max_step_m[name] = 0.0
		_report.max_unexplained_m[name] = 0.0


## A post the size of the addon's sandbag where the policy aims, riding along with the parent: a kinematic body
## (a pinned sandbag carried this way would be torn from its pin every frame and swing into the arms).
func _target() -> Node3D:
	var post := AnimatableBody3D.new()
	post.name = "Post"
	post.sync_to_physics = false
	post.position = PunchSpec.default_target_offset()
	post.collision_layer = 4
	post.collision_mask = 2
	var shape := CollisionShape3D.new()
	shape.shape = CylinderShape3D.new()
	shape.shape.radius = 0.175
	shape.shape.height = 1.0
	post.add_child(shape)
	_mover.add_child(post)
	return post


## The body's pose now: the pelvis's from the physics server (its node holds the target of the coming step).
func _pose(name: String) -> Transform3D:
	var body: PhysicsBody3D = _character.get_node(name)
	return PhysicsServer3D.body_get_state(body.get_rid(), PhysicsServer3D.BODY_STATE_TRANSFORM)


func _velocity(name: String) -> Vector3:
	var body: PhysicsBody3D = _character.get_node(name)
	return PhysicsServer3D.body_get_state(body.get_rid(), PhysicsServer3D.BODY_STATE_LINEAR_VELOCITY)


func _physics_process(delta: float) -> bool:
	_frames += 1
	if _frames == 1:
		_pelvis_rest = _character.global_transform.affine_inverse() * _pose("Pelvis")
		for joint in JOINTS:
			var at: Vector3 = (_character.get_node(joint[0]) as Node3D).global_position
			_anchors.append([_pose(joint[1]).affine_inverse() * at, _pose(joint[2]).affine_inverse() * at])
	else:
		_measure(delta)
	if _frames == _punch_at and _controller.get("policy") != null:
		_report.punch_started = _controller.call("punch")
	if _frames <= MOVING_FRAMES:
		# As a game moves a CharacterBody3D: a walk along the character's own front, turning as it goes.
		_mover.rotate_y(_turn * delta)
		_mover.position += _mover.basis.z * _speed * delta
	elif _frames == MOVING_FRAMES + 1:
		for name in BODIES:
			_before_teleport[name] = _character.global_transform.affine_inverse() * _pose(name)
		_mover.position += TELEPORT
		_mover.rotate_y(PI / 2.0)
	elif _frames == MOVING_FRAMES + 2:
		var root_now: Transform3D = _character.global_transform
		for name in BODIES:
			var carried: Transform3D = root_now * _before_teleport[name]
			_report.teleport_pose_error_m[name] = carried.origin.distance_to(_pose(name).origin)
		_report.teleport_pelvis_error_m = (root_now * _pelvis_rest).origin.distance_to(_pose("Pelvis").origin)
		_report.teleport_max_speed_mps = 0.0
		for name in BODIES:
			_report.teleport_max_speed_mps = maxf(_report.teleport_max_speed_mps, _velocity(name).length())
	if _frames > MOVING_FRAMES + 30:
		_report.punched = _report.finished.size() > 0
		print("MOVING_CHARACTER ", JSON.stringify(_report))
		quit(0)
	return false


## One frame's measures, read after the step (before the parent moves again); the teleport frame is left out.
func _measure(delta: float) -> void:
	var teleported := _frames == MOVING_FRAMES + 2
	if not teleported:
		for name in BODIES:
			var now := _pose(name)
			if _last.has(name):
				var step: Vector3 = now.origin - _last[name].origin
				_report.max_step_m[name] = maxf(_report.max_step_m[name], step.length())
				# Jolt moves a body by its velocity after the step, then corrects positions a little (joints).
				var unexplained := (step - _velocity(name) * delta).length()
				_report.max_unexplained_m[name] = maxf(_report.max_unexplained_m[name], unexplained)
	if _frames <= MOVING_FRAMES + 1 and _frames > 2:
		# The pelvis after the step: where the root was carried to in the last frame.
		var wanted: Transform3D = _character.global_transform * _pelvis_rest
		var pelvis := _pose("Pelvis")
		_report.max_pelvis_error_m = maxf(_report.max_pelvis_error_m, wanted.origin.distance_to(pelvis.origin))
		var turn_error := wanted.basis.get_rotation_quaternion().angle_to(pelvis.basis.get_rotation_quaternion())
		_report.max_pelvis_turn_error_rad = maxf(_report.max_pelvis_turn_error_rad, turn_error)
		if _last.has("Pelvis"):
			var moved_at: Vector3 = (pelvis.origin - _last["Pelvis"].origin) / delta
			var rid: RID = (_character.get_node("Pelvis") as PhysicsBody3D).get_rid()
			var spin: Vector3 = PhysicsServer3D.body_get_state(rid, PhysicsServer3D.BODY_STATE_ANGULAR_VELOCITY)
			var error := (moved_at - _velocity("Pelvis")).length()
			_report.max_pelvis_velocity_error_mps = maxf(_report.max_pelvis_velocity_error_mps, error)
			_report.pelvis_speed_mps = _velocity("Pelvis").length()
			_report.pelvis_spin_radps = spin.y
	for joint_index in JOINTS.size():
		var joint: Array = JOINTS[joint_index]
		var parent_at: Vector3 = _pose(joint[1]) * (_anchors[joint_index][0] as Vector3)
		var child_at: Vector3 = _pose(joint[2]) * (_anchors[joint_index][1] as Vector3)
		_report.max_joint_gap_m = maxf(_report.max_joint_gap_m, parent_at.distance_to(child_at))
	for name in BODIES:
		_last[name] = _pose(name)
