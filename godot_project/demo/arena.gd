## What the duel and crowd demos share: a lit floor, a camera, a label for the hit rate, and how many punches
## to play before quitting when run with `-- --punches=N` (headless tests); without it they go on forever.
extends Node3D

const CHARACTER_SCENE := preload("res://addons/punch_controller/scenes/punch_character.tscn")
const STRAIGHT_POLICY := preload("res://addons/punch_controller/policies/straight.onnx")

## Punches to play before printing the hit rate and quitting (0: never quit).
var punch_limit := 0
var punches := 0
var punches_that_hit := 0
var _label := Label.new()


func _init() -> void:
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--punches="):
			punch_limit = int(argument.trim_prefix("--punches="))


## Sets up the floor, light, camera (at `camera_at`, looking at the origin) and the hit-rate label.
func build_stage(camera_at: Vector3) -> void:
	var floor_mesh := MeshInstance3D.new()
	var plane := PlaneMesh.new()
	plane.size = Vector2(40, 40)
	floor_mesh.mesh = plane
	add_child(floor_mesh)
	var sun := DirectionalLight3D.new()
	sun.rotation_degrees = Vector3(-50, 30, 0)
	sun.shadow_enabled = true
	add_child(sun)
	var camera := Camera3D.new()
	add_child(camera)
	camera.look_at_from_position(camera_at, Vector3(0, 1, 0))
	var layer := CanvasLayer.new()
	add_child(layer)
	_label.position = Vector2(16, 16)
	layer.add_child(_label)


## Adds a sky that lights the scene (the rendered GIFs' look) under `parent`.
static func add_sky(parent: Node) -> void:
	var environment := Environment.new()
	var sky_material := ProceduralSkyMaterial.new()
	sky_material.sky_top_color = Color(0.32, 0.42, 0.58)
	environment.background_mode = Environment.BG_SKY
	environment.sky = Sky.new()
	environment.sky.sky_material = sky_material
	environment.ambient_light_source = Environment.AMBIENT_SOURCE_SKY
	environment.ambient_light_energy = 0.6
	environment.tonemap_mode = Environment.TONE_MAPPER_FILMIC
	var world := WorldEnvironment.new()
	world.environment = environment
	parent.add_child(world)


## A character at `where` (its +Z is where it faces), added under `parent`.
func add_character(parent: Node3D, where: Transform3D) -> Node3D:
	var character: Node3D = CHARACTER_SCENE.instantiate()
	character.transform = where
	parent.add_child(character)
	return character


## A controller for `character` aiming at `target`, with the straight-punch policy.
func add_controller(character: Node3D, target: Node3D, noise_sigma: float, seed: int) -> PunchController:
	var controller := PunchController.new()
	controller.character = character
	controller.target = target
	controller.policy = STRAIGHT_POLICY
	controller.noise_sigma = noise_sigma
	controller.seed = seed
	add_child(controller)
	return controller


## Counts a finished punch; prints the hit rate and quits after `punch_limit` punches.
## A label 2.1 m above `origin` (a character's feet), turned to the camera when `billboard`.
func add_label_above(origin: Vector3, billboard := false) -> Label3D:
	var label := Label3D.new()
	label.position = origin + Vector3(0, 2.1, 0)
	label.pixel_size = 0.006
	label.font_size = 36
	label.outline_size = 12
	if billboard:
		label.billboard = BaseMaterial3D.BILLBOARD_ENABLED
	add_child(label)
	return label


func count_punch(hit: bool, name_of_scene: String) -> void:
	punches += 1
	punches_that_hit += int(hit)
	var rate := float(punches_that_hit) / punches
	_label.text = "%s: %d of %d punches hit (%.0f%%)" % [name_of_scene, punches_that_hit, punches, 100.0 * rate]
	if punch_limit > 0 and punches == punch_limit:
		print("HIT_RATE ", JSON.stringify({"scene": name_of_scene, "punches": punches, "hits": punches_that_hit, "rate": rate}))
		get_tree().quit()
