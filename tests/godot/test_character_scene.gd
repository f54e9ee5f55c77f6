## Headless test of the addon's character scene used as a game uses it (nodes in the scene tree): it
## configures its joints from the DOF table, turns off collisions between its own bodies, and holds still.
## The scene must already hold the DOF table's joint settings, so that `ready` rebuilds no Jolt constraint
## (which would reorder Jolt's solver and make the game step differently from the training server).
extends SceneTree

const BODIES := ["Pelvis", "Torso", "UpperArmR", "ForearmR", "UpperArmL", "ForearmL"]
const JOINTS := ["Waist", "ShoulderR", "ElbowR", "ShoulderL", "ElbowL"]

var _character: Node3D
var _start := {}
var _frames := 0
var _failures: Array[String] = []
var _stored_joint_settings := []


func _initialize() -> void:
	_character = load("res://addons/punch_controller/scenes/punch_character.tscn").instantiate()
	_stored_joint_settings = _joint_settings()
	root.add_child(_character)


func _physics_process(_delta: float) -> bool:
	_frames += 1
	if _frames == 1:
		_check_setup()
		for name in BODIES:
			_start[name] = (_character.get_node(name) as Node3D).global_position
	elif _frames == 120:
		for name in BODIES:
			var moved: float = (_character.get_node(name) as Node3D).global_position.distance_to(_start[name])
			_check(moved < 0.005, "%s moved %.4f m in 1 s at rest" % [name, moved])
		for failure in _failures:
			printerr("FAILED: ", failure)
		print("test_character_scene: %s" % ("ok" if _failures.is_empty() else "%d failure(s)" % _failures.size()))
		quit(0 if _failures.is_empty() else 1)
	return false


func _check(condition: bool, message: String) -> void:
	if not condition:
		_failures.append(message)


## Every limit, motor and flag of every joint, in a fixed order.
func _joint_settings() -> Array:
	var values := []
	for name in JOINTS:
		var joint: Generic6DOFJoint3D = _character.get_node(name)
		for param in Generic6DOFJoint3D.PARAM_MAX:
			values.append([name, "param", param, joint.get_param_x(param), joint.get_param_y(param), joint.get_param_z(param)])
		for flag in Generic6DOFJoint3D.FLAG_MAX:
			values.append([name, "flag", flag, joint.get_flag_x(flag), joint.get_flag_y(flag), joint.get_flag_z(flag)])
	return values


func _check_setup() -> void:
	_check(_character.call("is_ready_to_punch"), "the character is ready")
	var configured := _joint_settings()
	for i in configured.size():
		_check(configured[i] == _stored_joint_settings[i], "the scene stores %s; ready made it %s: rerun tools/build_scenes.gd" % [_stored_joint_settings[i], configured[i]])
	var elbow: Generic6DOFJoint3D = _character.get_node("ElbowR")
	# Action range -25..118 degrees, mirrored for Godot and widened by the 10 degree hard-limit margin.
	_check(is_equal_approx(elbow.get_param_x(Generic6DOFJoint3D.PARAM_ANGULAR_LOWER_LIMIT), deg_to_rad(-128.0)), "elbow lower limit")
	_check(is_equal_approx(elbow.get_param_x(Generic6DOFJoint3D.PARAM_ANGULAR_UPPER_LIMIT), deg_to_rad(35.0)), "elbow upper limit")
	_check(elbow.get_flag_x(Generic6DOFJoint3D.FLAG_ENABLE_MOTOR), "elbow X has a motor")
	_check(not elbow.get_flag_y(Generic6DOFJoint3D.FLAG_ENABLE_MOTOR), "elbow Y is locked, no motor")
	_check(is_equal_approx(elbow.get_param_x(Generic6DOFJoint3D.PARAM_ANGULAR_MOTOR_FORCE_LIMIT), 60.0), "elbow torque limit")
	# An exception on either body of a pair keeps the pair from colliding.
	for i in BODIES.size():
		for j in range(i + 1, BODIES.size()):
			var a: PhysicsBody3D = _character.get_node(BODIES[i])
			var b: PhysicsBody3D = _character.get_node(BODIES[j])
			_check(b in a.get_collision_exceptions() or a in b.get_collision_exceptions(), "%s and %s must not collide" % [BODIES[i], BODIES[j]])
