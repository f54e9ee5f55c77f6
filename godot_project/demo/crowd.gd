## Twenty characters facing every way, each punching its own sandbag in front of it (straight punches, noise
## sigma 0.1, a seed each): after each punch and the return to guard, the bag is stopped and the character
## punches again. Prints the share of punches that hit.
extends "res://demo/arena.gd"

const COUNT := 20
const SANDBAG_SCENE := preload("res://addons/punch_controller/scenes/punch_sandbag.tscn")


func _ready() -> void:
	build_stage(Vector3(0, 14, 16))
	var random := RandomNumberGenerator.new()
	random.seed = 11
	for index in COUNT:
		# On a 5 x 4 grid, each turned its own way.
		var where := Transform3D(Basis(Vector3.UP, random.randf_range(-PI, PI)),
			Vector3(3.0 * (index % 5) - 6.0, 0, 3.0 * (index / 5) - 4.5))
		var character := add_character(self, where)
		var sandbag: Node3D = SANDBAG_SCENE.instantiate()
		# The spec's target offset is in the character's frame: turned with it (look_at-friendly: the
		# character faces its +Z, so `look_at` would point its -Z at the bag; place it like this instead).
		sandbag.transform = Transform3D(where.basis, where * PunchSpec.default_target_offset())
		add_child(sandbag)
		var bag: RigidBody3D = sandbag.get_node("Bag")
		var controller := add_controller(character, bag, 0.1, index + 1)
		var landed := [false]
		controller.hit.connect(func(_impulse, _speed, _position, body, _push, _hand, _part, _blocked): landed[0] = landed[0] or body == bag)
		controller.punch_finished.connect(func(_metrics):
			count_punch(landed[0], "crowd")
			landed[0] = false)
		controller.recovered.connect(func():
			_stop(bag, sandbag.transform)
			controller.punch())
		controller.punch.call_deferred()


## Puts a bag back at rest where it hangs (a swinging bag is a different target from the trained one).
func _stop(bag: RigidBody3D, sandbag_transform: Transform3D) -> void:
	bag.global_transform = sandbag_transform
	bag.linear_velocity = Vector3.ZERO
	bag.angular_velocity = Vector3.ZERO
