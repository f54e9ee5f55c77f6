## The scene `punch render` films in Movie Maker mode: one character and sandbag per noise sigma, side by side
## (each pair on its own collision layers, at most 16), every character punching again and again from its
## guard pose.
## Arguments after `--`: --policy=PATH --sigmas=0,0.3,0.6 [--noise-decisions=-1] [--seed=0]
## [--bags=d,h,s;d,h,s;...: each pair's bag placement in metres (distance, height, side), cycled; default:
## the training's default placement]
extends Node3D

const PunchPair := preload("res://tools/punch_pair.gd")
const ARENA := preload("res://demo/arena.gd")
## Metres between neighbouring pairs (arms and swinging bags never reach the next pair).
const SPACING_M := 2.2
## Seconds of rest between punches.
const PAUSE_S := 0.35

var _options := {"policy": "", "sigmas": "0", "noise-decisions": "-1", "seed": "0", "bags": ""}


func _ready() -> void:
	for argument in OS.get_cmdline_user_args():
		var parts := argument.trim_prefix("--").split("=", true, 1)
		if parts.size() == 2 and _options.has(parts[0]):
			_options[parts[0]] = parts[1]
		else:
			printerr("error: render: unknown argument '%s'" % argument)
			get_tree().quit(2)
			return
	var sigmas: PackedFloat64Array = (_options.sigmas as String).split_floats(",")
	_build_stage(sigmas.size())
	for index in sigmas.size():
		_add_pair(index, sigmas.size(), sigmas[index])


func _add_pair(index: int, count: int, sigma: float) -> void:
	# The camera looks from behind the characters' right: ascending sigma from left to right on screen.
	var x := ((count - 1) / 2.0 - index) * SPACING_M
	var stand := MeshInstance3D.new()
	var stand_mesh := CylinderMesh.new()
	stand_mesh.top_radius = 0.06
	stand_mesh.bottom_radius = 0.2
	stand_mesh.height = 0.96
	stand.mesh = stand_mesh
	stand.position = Vector3(x, 0.48, 0)
	add_child(stand)
	var offset := PunchSpec.default_target_offset()
	if _options.bags != "":
		var bags := (_options.bags as String).split(";")
		var bag_m := bags[index % bags.size()].split_floats(",")
		offset = Vector3(bag_m[2], bag_m[1], bag_m[0])
	var controller := PunchPair.add(self, index, Vector3(x, 0, 0), offset, _options.policy, sigma,
		int(_options["noise-decisions"]), int(_options.seed) + index)
	var character: Node3D = controller.get("character")
	var bag: RigidBody3D = controller.get("target")
	var label := Label3D.new()
	label.text = "sigma %.2f" % sigma
	label.font_size = 64
	label.outline_size = 12
	label.billboard = BaseMaterial3D.BILLBOARD_ENABLED
	label.position = Vector3(x, 2.25, 0.3)
	add_child(label)
	var bag_rest := bag.global_transform
	var timer := Timer.new()
	timer.one_shot = true
	timer.wait_time = PAUSE_S
	add_child(timer)
	var punch := func():
		character.reset_pose()
		bag.global_transform = bag_rest
		bag.linear_velocity = Vector3.ZERO
		bag.angular_velocity = Vector3.ZERO
		controller.punch()
	timer.timeout.connect(punch)
	controller.connect("punch_finished", func(_metrics): timer.start())
	punch.call_deferred()


func _build_stage(count: int) -> void:
	ARENA.add_sky(self)
	var sun := DirectionalLight3D.new()
	sun.shadow_enabled = true
	sun.look_at_from_position(Vector3(0, 4, 0), Vector3(0.7, 3, -0.6))
	add_child(sun)
	var floor_mesh := PlaneMesh.new()
	floor_mesh.size = Vector2(SPACING_M * count + 4, 8)
	var floor_material := StandardMaterial3D.new()
	floor_material.albedo_color = Color(0.36, 0.33, 0.3)
	floor_mesh.material = floor_material
	var floor_instance := MeshInstance3D.new()
	floor_instance.mesh = floor_mesh
	add_child(floor_instance)
	var camera := Camera3D.new()
	camera.fov = 45
	var width := SPACING_M * (count - 1)
	var eye := Vector3(-2.3 - 0.5 * width, 2.2 + 0.2 * width, -1.7 - 0.4 * width)
	camera.look_at_from_position(eye, Vector3(0, 1.2, 0.4))
	add_child(camera)
	camera.make_current()
