## Two characters punch each other in turn (straight punches, noise sigma 0.1), each aiming at the other's
## torso. After every exchange the pair moves to a new place on the floor and turns to a new heading. Prints
## the share of punches that land on the opponent.
extends "res://demo/arena.gd"

## Distance between the two characters' roots, m: the trained target offset ahead (the opponent's torso
## stands where a sandbag's centre would).
var _distance_m: float = PunchSpec.default_target_offset().z
var _pair := Node3D.new()
var _fighters: Array[Node3D] = []
var _controllers: Array[PunchController] = []
var _landed := false
var _turn := 0
var _random := RandomNumberGenerator.new()


func _ready() -> void:
	_random.seed = 7
	build_stage(Vector3(3.5, 2.5, 3.5))
	add_child(_pair)
	var facing_each_other := [Transform3D.IDENTITY, Transform3D(Basis(Vector3.UP, PI), Vector3(0, 0, _distance_m))]
	for where in facing_each_other:
		_fighters.append(add_character(_pair, where))
	for index in 2:
		var opponent := _fighters[1 - index]
		var controller := add_controller(_fighters[index], opponent.get_node("Torso"), 0.1, index + 1)
		controller.hit.connect(func(_impulse, _speed, _position, body, _push, _hand, _part, _blocked):
			_landed = _landed or (body != null and opponent.is_ancestor_of(body)))
		# Its own punch's recovery, not the one from being struck (`react_to_hits`), hands the turn over.
		controller.recovered.connect(func(): if _turn % 2 == index: _next())
		controller.punch_finished.connect(func(_metrics): count_punch(_landed, "duel"))
		_controllers.append(controller)
	_start_punch.call_deferred()


func _start_punch() -> void:
	_landed = false
	_controllers[_turn % 2].punch()


## After a punch and its recovery: the other one's turn; after both, move and turn the pair.
func _next() -> void:
	_turn += 1
	if _turn % 2 == 0:
		_pair.transform = Transform3D(Basis(Vector3.UP, _random.randf_range(-PI, PI)),
			Vector3(_random.randf_range(-5, 5), 0, _random.randf_range(-5, 5)))
		for fighter in _fighters:
			fighter.reset_pose()
	_start_punch()
