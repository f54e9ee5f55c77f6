## Renders skinned characters (.glb, loaded at run time with GLTFDocument) side by side into one PNG: each in its
## rest pose beside a copy with the right arm turned forward (a jab), to see the skin deform with the bones.
##   xvfb-run godot --rendering-driver opengl3 --path godot_project --script tests/godot/render_character.gd -- \
##       --out=/tmp/characters.png a.glb b.glb
## Needs a display (Xvfb) and OpenGL: not run by the test suite.
extends SceneTree

const SPACING_M := 1.4
var _out := "characters.png"
var _frames := 0


func _initialize() -> void:
	_build.call_deferred()  # once the root is inside the tree, so that bone poses update


func _build() -> void:
	var paths := []
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--out="):
			_out = argument.trim_prefix("--out=")
		else:
			paths.append(argument)
	var x := 0.0
	for path in paths:
		for posed in [false, true]:
			var document := GLTFDocument.new()
			var state := GLTFState.new()
			if document.append_from_file(path, state) != OK:
				printerr("cannot load ", path)
				quit(1)
				return
			var scene: Node3D = document.generate_scene(state)
			scene.position.x = x
			root.add_child(scene)
			if posed:
				_jab(scene, state)
			x += SPACING_M * (0.6 if not posed else 1.0)
	var width := x - SPACING_M
	var camera := Camera3D.new()
	root.add_child(camera)
	# From the front and a little to the characters' right, so that a forward arm shows its length.
	camera.fov = 40.0
	camera.look_at_from_position(Vector3(width / 2.0 - 1.2, 1.3, width * 0.95 + 1.5), Vector3(width / 2.0, 0.95, 0.0))
	var sun := DirectionalLight3D.new()
	sun.rotation_degrees = Vector3(-40, 30, 0)
	root.add_child(sun)
	var environment := WorldEnvironment.new()
	environment.environment = Environment.new()
	environment.environment.background_mode = Environment.BG_COLOR
	environment.environment.background_color = Color(0.93, 0.93, 0.95)
	environment.environment.ambient_light_source = Environment.AMBIENT_SOURCE_COLOR
	environment.environment.ambient_light_color = Color(0.5, 0.5, 0.55)
	root.add_child(environment)


## Turns the right upper arm so that shoulder -> wrist points forward (+Z).
func _jab(scene: Node, state: GLTFState) -> void:
	var skeleton: Skeleton3D = scene.find_children("*", "Skeleton3D", true, false)[0]
	var roles: Dictionary = state.json["extras"]["punch_character"]["roles"]
	var upper := _find_bone(skeleton, roles["upper_arm_r"])
	var hand := _find_bone(skeleton, roles["hand_r"])
	var upper_global := skeleton.get_bone_global_pose(upper)
	var arm := (skeleton.get_bone_global_pose(hand).origin - upper_global.origin).normalized()
	var turn := Basis(arm.cross(Vector3.BACK).normalized(), arm.angle_to(Vector3.BACK))
	var parent_global := skeleton.get_bone_global_pose(skeleton.get_bone_parent(upper))
	var local := parent_global.affine_inverse() * Transform3D(turn * upper_global.basis, upper_global.origin)
	skeleton.set_bone_pose_rotation(upper, local.basis.get_rotation_quaternion())


## Godot keeps glTF names except characters a node name cannot hold (`mixamorig:Hips` becomes `mixamorig_Hips`).
func _find_bone(skeleton: Skeleton3D, name: String) -> int:
	var bone := skeleton.find_bone(name)
	return bone if bone >= 0 else skeleton.find_bone(name.validate_node_name())


func _process(_delta: float) -> bool:
	_frames += 1
	if _frames < 4:
		return false
	var error := root.get_texture().get_image().save_png(_out)
	print("render_character: wrote ", _out if error == OK else "nothing (%s)" % error_string(error))
	quit(0 if error == OK else 1)
	return true
