## Two characters circle each other and trade punches while they move. Each is the addon's character under a
## CharacterBody3D that this script moves in `_physics_process` (as a game moves its characters: walking,
## strafing, turning every physics frame), with a PunchController aiming at the other's torso; the simulated
## body follows its mover during the punches, and the arms feel the motion through the joints.
##
## You are the blue character (the AI is red): W/S or Up/Down step toward and away from the opponent, A/D or
## Left/Right circle it (both characters always turn to face each other), Space or J punches, 1/2/3 pick the
## straight, hook or swing. Until the first key press an autopilot plays your side, so the scene plays by itself
## (`punch render --scene moving_duel`). The other character circles you at 0.7-1.1 m/s, steps in when it is
## ready, and punches when your torso is within its policy's reach.
##
## Arguments after `--`: `--autoplay` (the autopilot keeps your side; keys are ignored) and `--straight=PATH`,
## `--hook=PATH`, `--swing=PATH` (other policy files than the addon's). tests/godot/moving_duel_run.gd plays this
## scene and measures it from outside.
extends Node3D

const CHARACTER_SCENE := preload("res://addons/punch_controller/scenes/punch_character.tscn")
const ARENA := preload("res://demo/arena.gd")
const STYLES := ["straight", "hook", "swing"]
## Distance between the two roots while circling, m (out of reach: the trained target distances are 0.6-0.85 m).
const STANDOFF_M := 1.1
## Walking speed of the keyboard side, m/s.
const WALK_MPS := 1.0
## Largest speed of a mover (the policies are trained walking at up to 1.4 m/s), m/s.
const MAX_SPEED_MPS := 1.3
## How fast a character turns to face its opponent at most (the policies are trained turning up to 120°/s).
const MAX_TURN_RADPS := deg_to_rad(120.0)
## How far a mover's velocity changes per second at most, m/s² (a walk, not a teleporting velocity).
const ACCELERATION := 6.0
## Where the camera stands from what it looks at, m: above, beside the fighters' first line and a little behind
## the AI (you on the left; the pair turns away from the camera's line at first, so the first exchange is seen
## from the side).
const CAMERA_OFFSET := Vector3(-1.9, 3.1, 1.6)
## The mover's physics layer (layer 8): the two movers bump into each other, nothing else touches them.
const MOVER_LAYER := 1 << 7

var _fighters: Array[Fighter] = []
var _autoplay_only := false
var _policies := {}
var _reaches := {}
var _label := Label.new()
var _camera := Camera3D.new()
var _camera_looks_at := Vector3.ZERO
var _camera_follows := false


## One side: its mover, character and controller, what steers it, and what it did.
class Fighter:
	var name: String
	var mover: CharacterBody3D
	var character: Node3D
	var controller: PunchController
	var opponent: Fighter
	## "keys" (the keyboard) or "auto" (the AI, or the autopilot of your side).
	var driver := "auto"
	var style := "straight"
	var random := RandomNumberGenerator.new()
	## The AI's plan: "circle", "step_in", "punch" or "back_off", the seconds left in it, and its way round.
	var plan := "circle"
	var plan_left_s := 0.0
	var circle_sign := 1.0
	var circle_mps := 0.9
	var next_flip_s := 3.0
	## This punch struck the opponent (`hit`), on its trunk (`on_body`).
	var hit := false
	var on_body := false
	var punches := 0
	var hits := 0
	var hits_on_body := 0

	## The opponent's torso in this character's frame (+Z ahead, +Y up, +X its left).
	func target_offset() -> Vector3:
		return character.global_transform.affine_inverse() * controller.target.global_position

	func distance() -> float:
		var between := opponent.mover.global_position - mover.global_position
		return Vector2(between.x, between.z).length()


func _ready() -> void:
	var paths := {}
	for style in STYLES:
		paths[style] = "res://addons/punch_controller/policies/%s.onnx" % style
	for argument in OS.get_cmdline_user_args():
		var parts := argument.trim_prefix("--").split("=", true, 1)
		if parts[0] == "autoplay":
			_autoplay_only = true
		elif parts[0] in STYLES and parts.size() == 2:
			paths[parts[0]] = parts[1]
	for style in STYLES:
		var policy := load(paths[style])
		if policy != null:
			_policies[style] = policy
	_build_stage()
	# You stand at the origin facing +Z, the opponent ahead of you, facing you.
	var you := _add_fighter("you", Vector3.ZERO, 0.0, 1, Color.TRANSPARENT)
	var ai := _add_fighter("AI", Vector3(0, 0, STANDOFF_M), PI, 2, Color(0.72, 0.2, 0.16))
	you.opponent = ai
	ai.opponent = you
	for fighter in _fighters:
		fighter.controller.target = fighter.opponent.character.get_node("Torso")
	# Both circle the same way round (so the pair turns); the AI attacks first.
	ai.plan_left_s = 0.5
	ai.circle_mps = 0.8
	you.circle_mps = 0.5
	you.plan_left_s = 1.0
	_camera_looks_at = Vector3(0, 0, STANDOFF_M / 2.0)


## Paints the character's trunk (the addon's is blue) `color`.
func _paint(character: Node3D, color: Color) -> void:
	var material := StandardMaterial3D.new()
	material.albedo_color = color
	for mesh_path in ["Pelvis/PelvisShapeMesh", "Torso/TorsoShapeMesh"]:
		(character.get_node(mesh_path) as MeshInstance3D).material_override = material


func _add_fighter(fighter_name: String, where: Vector3, yaw: float, seed: int, color: Color) -> Fighter:
	var fighter := Fighter.new()
	fighter.name = fighter_name
	fighter.random.seed = seed * 7919
	var mover := CharacterBody3D.new()
	mover.name = fighter_name.capitalize()
	mover.position = where
	mover.rotation.y = yaw
	mover.motion_mode = CharacterBody3D.MOTION_MODE_FLOATING
	mover.collision_layer = MOVER_LAYER
	mover.collision_mask = MOVER_LAYER
	var shape := CollisionShape3D.new()
	shape.shape = CapsuleShape3D.new()
	shape.shape.radius = 0.25
	shape.shape.height = 1.7
	shape.position.y = 0.85
	mover.add_child(shape)
	add_child(mover)
	fighter.mover = mover
	fighter.character = CHARACTER_SCENE.instantiate()
	mover.add_child(fighter.character)
	if color != Color.TRANSPARENT:
		_paint(fighter.character, color)
	var controller := PunchController.new()
	controller.name = fighter_name.capitalize() + "Controller"
	controller.character = fighter.character
	controller.policy = _policies.get("straight")
	controller.noise_sigma = 0.1
	controller.seed = seed
	add_child(controller)
	fighter.controller = controller
	# A punch hits when a fist strikes the opponent: its trunk (the target), or the guard in front of it.
	controller.hit.connect(func(_impulse, _speed, _position, body, _push, _hand, _part, _blocked):
		if body != null and fighter.opponent.character.is_ancestor_of(body):
			fighter.hit = true
			fighter.on_body = fighter.on_body or body == fighter.controller.target)
	controller.punch_finished.connect(func(_metrics):
		fighter.punches += 1
		fighter.hits += int(fighter.hit)
		fighter.hits_on_body += int(fighter.on_body)
		if fighter.plan == "punch":
			_start_plan(fighter, "back_off", 0.7))
	_fighters.append(fighter)
	return fighter


func _unhandled_key_input(event: InputEvent) -> void:
	var key := event as InputEventKey
	if _autoplay_only or key == null or not key.pressed or key.echo:
		return
	var you := _fighters[0]
	if you.driver != "keys":
		you.driver = "keys"
		you.plan = "circle"
	match key.physical_keycode:
		KEY_SPACE, KEY_J:
			_punch(you)
		KEY_1, KEY_2, KEY_3:
			you.style = STYLES[key.physical_keycode - KEY_1]


func _physics_process(delta: float) -> void:
	for fighter in _fighters:
		var wanted: Vector3 = _keys_velocity(fighter) if fighter.driver == "keys" else _ai_velocity(fighter, delta)
		_move(fighter, wanted, delta)
	_follow_with_camera(delta)
	_show_score()


## Walks the mover toward `wanted` (global, m/s) and turns it toward its opponent, as a game moves a
## CharacterBody3D: velocity, `move_and_slide()`, and a turn of the node, every physics frame.
func _move(fighter: Fighter, wanted: Vector3, delta: float) -> void:
	var mover := fighter.mover
	wanted = wanted.limit_length(MAX_SPEED_MPS)
	mover.velocity = mover.velocity.move_toward(wanted, ACCELERATION * delta)
	mover.move_and_slide()
	var to_opponent := fighter.opponent.mover.global_position - mover.global_position
	var facing := atan2(to_opponent.x, to_opponent.z)
	var turn := clampf(angle_difference(mover.rotation.y, facing), -MAX_TURN_RADPS * delta, MAX_TURN_RADPS * delta)
	mover.rotation.y = wrapf(mover.rotation.y + turn, -PI, PI)


## WASD or the arrows, relative to facing the opponent.
func _keys_velocity(fighter: Fighter) -> Vector3:
	var ahead := _pressed(KEY_W, KEY_UP) - _pressed(KEY_S, KEY_DOWN)
	var left := _pressed(KEY_A, KEY_LEFT) - _pressed(KEY_D, KEY_RIGHT)
	return fighter.mover.global_basis * (Vector3(left, 0, ahead).limit_length(1.0) * WALK_MPS)


func _pressed(key: Key, other: Key) -> float:
	return float(Input.is_physical_key_pressed(key) or Input.is_physical_key_pressed(other))


## The AI (and your autopilot): circle the opponent at the standoff distance, now and then step in, punch when
## the opponent's torso is within the policy's reach, and back off when the punch is over; it keeps circling
## the while, a little slower.
func _ai_velocity(fighter: Fighter, delta: float) -> Vector3:
	fighter.plan_left_s -= delta
	fighter.next_flip_s -= delta
	if fighter.next_flip_s <= 0.0:
		fighter.circle_sign = -fighter.circle_sign
		fighter.next_flip_s = fighter.random.randf_range(2.5, 4.5)
	var distance := STANDOFF_M
	var circling := fighter.circle_mps
	var opponent_engaged := fighter.opponent.plan in ["step_in", "punch"] or fighter.opponent.controller.is_punching()
	match fighter.plan:
		"circle":
			# Its turn to attack once the opponent is not attacking; meanwhile it holds its ground.
			if opponent_engaged:
				distance = clampf(fighter.distance(), 0.6, STANDOFF_M)
			elif fighter.plan_left_s <= 0.0:
				_start_plan(fighter, "step_in", 1.5)
		"step_in":
			distance = _strike_distance(fighter)
			circling *= 0.6
			if _in_reach(fighter) and _punch(fighter):
				_start_plan(fighter, "punch", 2.0)
			elif fighter.plan_left_s <= 0.0:
				_start_plan(fighter, "back_off", 0.5)
		"punch":
			distance = _strike_distance(fighter)
			circling *= 0.6
			if fighter.plan_left_s <= 0.0:
				_start_plan(fighter, "back_off", 0.5)
		"back_off":
			if fighter.plan_left_s <= 0.0:
				_start_plan(fighter, "circle", fighter.random.randf_range(0.4, 1.2))
				if fighter != _fighters[0]:
					fighter.circle_mps = fighter.random.randf_range(0.7, 1.1)
	var to_opponent := fighter.opponent.mover.global_position - fighter.mover.global_position
	to_opponent.y = 0.0
	var toward := to_opponent.normalized()
	var around := toward.cross(Vector3.UP) * fighter.circle_sign
	var closing := clampf(2.5 * (to_opponent.length() - distance), -1.0, 1.0)
	return toward * closing + around * circling


func _start_plan(fighter: Fighter, plan: String, seconds: float) -> void:
	fighter.plan = plan
	fighter.plan_left_s = seconds
	if plan == "step_in" and fighter.driver == "auto":
		# The AI varies its punches: mostly straights.
		var pick := fighter.random.randf()
		var style: String = "straight" if pick < 0.6 else ("hook" if pick < 0.8 else "swing")
		fighter.style = style if _policies.has(style) else "straight"


## Where to stand to punch: the middle of the policy's trained target distances.
func _strike_distance(fighter: Fighter) -> float:
	var reach := _reach(fighter)
	return PunchSpec.default_target_offset().z if reach.is_empty() else (reach.distance_m.x + reach.distance_m.y) / 2.0


## The opponent's torso is within the policy's trained reach (2 cm inside its edges).
func _in_reach(fighter: Fighter) -> bool:
	var reach := _reach(fighter)
	if reach.is_empty():
		return false
	var offset := fighter.target_offset()
	return _inside(offset.z, reach.distance_m) and _inside(offset.y, reach.height_m) and _inside(offset.x, reach.side_m)


func _inside(value: float, range_m: Vector2) -> bool:
	return value > range_m.x + 0.02 and value < range_m.y - 0.02


## The reach volume of the fighter's style (asked of its controller once per style; empty when the policy
## cannot be used, which the controller has said).
func _reach(fighter: Fighter) -> Dictionary:
	if not _reaches.has(fighter.style):
		fighter.controller.policy = _policies.get(fighter.style)
		_reaches[fighter.style] = fighter.controller.reach_volume() if _policies.has(fighter.style) else {}
	return _reaches[fighter.style]


## Punches with the fighter's style, unless a punch is running.
func _punch(fighter: Fighter) -> bool:
	if fighter.controller.is_punching() or not _policies.has(fighter.style):
		return false
	fighter.controller.policy = _policies[fighter.style]
	fighter.hit = false
	fighter.on_body = false
	return fighter.controller.punch()


## The camera stands still (so the circling shows against the floor) above and to the side of where the fight
## started, looking down at the fighters; it walks after them once their middle is more than 1.2 m from where it
## looks.
func _follow_with_camera(delta: float) -> void:
	var middle := (_fighters[0].mover.global_position + _fighters[1].mover.global_position) / 2.0
	if middle.distance_to(_camera_looks_at) > 1.2:
		_camera_follows = true
	if _camera_follows:
		_camera_looks_at = _camera_looks_at.move_toward(middle, 1.5 * delta)
		_camera_follows = _camera_looks_at.distance_to(middle) > 0.05
	var eye := _camera_looks_at + CAMERA_OFFSET
	_camera.look_at_from_position(eye, _camera_looks_at + Vector3(0, 0.9, 0))


func _show_score() -> void:
	var lines := PackedStringArray()
	for fighter in _fighters:
		lines.append("%s: %d of %d punches hit, %d on the body (%s)" % [fighter.name, fighter.hits, fighter.punches,
			fighter.hits_on_body, fighter.style])
	var you := _fighters[0]
	if _autoplay_only:
		lines.append("autoplay")
	elif you.driver == "auto":
		lines.append("autopilot: WASD/arrows move, Space/J punch, 1/2/3 style")
	_label.text = "\n".join(lines)


func _exit_tree() -> void:
	# The fighters point at each other: let go, so that they are freed.
	for fighter in _fighters:
		fighter.opponent = null


func _build_stage() -> void:
	ARENA.add_sky(self)
	var sun := DirectionalLight3D.new()
	sun.shadow_enabled = true
	sun.rotation_degrees = Vector3(-70, 30, 0)
	add_child(sun)
	# A checkered floor, 1 m squares, so that the walking shows.
	var checker := Image.create(2, 2, false, Image.FORMAT_RGB8)
	checker.fill(Color(0.3, 0.28, 0.26))
	checker.set_pixel(0, 0, Color(0.36, 0.33, 0.3))
	checker.set_pixel(1, 1, Color(0.36, 0.33, 0.3))
	var floor_material := StandardMaterial3D.new()
	floor_material.albedo_texture = ImageTexture.create_from_image(checker)
	floor_material.texture_filter = BaseMaterial3D.TEXTURE_FILTER_NEAREST
	floor_material.uv1_scale = Vector3(20, 20, 1)
	var floor_mesh := PlaneMesh.new()
	floor_mesh.size = Vector2(40, 40)
	floor_mesh.material = floor_material
	var floor_instance := MeshInstance3D.new()
	floor_instance.mesh = floor_mesh
	add_child(floor_instance)
	_camera.fov = 45
	add_child(_camera)
	_camera.make_current()
	var layer := CanvasLayer.new()
	add_child(layer)
	_label.position = Vector2(16, 16)
	_label.add_theme_color_override("font_outline_color", Color.BLACK)
	_label.add_theme_constant_override("outline_size", 8)
	_label.add_theme_font_size_override("font_size", 26)
	layer.add_child(_label)
