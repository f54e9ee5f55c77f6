## The six moves side by side: six characters in a row, each in its stance's guard (`stance_pose`) throwing its own
## move (1 jab ... 6 rear uppercut) at the sandbag on its punching hand's side, from the addon's moveset for the
## stance (`boxing_stance.tres`); every round the stance flips between orthodox and southpaw, so each move is thrown
## with either hand. Prints the share of punches that hit.
extends "res://demo/arena.gd"

const MOVES: Array[StringName] = [&"jab", &"cross", &"lead_hook", &"rear_hook", &"lead_uppercut", &"rear_uppercut"]
const SANDBAG_SCENE := preload("res://addons/punch_controller/scenes/punch_sandbag.tscn")
## The bag's centre this far toward the punching hand (m; +X is a character's left).
const SIDE_M := 0.1


func _ready() -> void:
	build_stage(Vector3(-0.8, 3.3, 6.4))
	add_sky(self)
	for index in MOVES.size():
		var where := Transform3D(Basis.IDENTITY, Vector3(1.7 * index - 4.25, 0, 0))
		var character := add_character(self, where)
		var controller := add_controller(character, null, 0.1, index + 1)
		controller.stance_pose = true  # and no moveset: the addon's for the stance, boxing_stance.tres
		var label := add_label_above(where.origin)
		var row := {"move": MOVES[index], "controller": controller, "sandbag": null, "bag": null, "label": label,
			"origin": where.origin, "landed": false}
		controller.hit.connect(func(_impulse, _speed, _position, body, _push, _hand, _part, _blocked):
			row.landed = row.landed or body == row.bag)
		controller.punch_finished.connect(func(_metrics):
			count_punch(row.landed, "moves")
			row.landed = false)
		controller.recovered.connect(func(): _throw(row, _next_stance(controller)))
		_throw.call_deferred(row, PunchController.ORTHODOX)


## The stance the next round of this controller uses: the other one.
func _next_stance(controller: PunchController) -> int:
	return PunchController.SOUTHPAW if controller.stance == PunchController.ORTHODOX else PunchController.ORTHODOX


## Hangs a new sandbag at rest on the punching hand's side (its rope's hook is fixed where it is made, so the old
## one goes) and throws the row's move in `stance`.
func _throw(row: Dictionary, stance: int) -> void:
	var controller: PunchController = row.controller
	controller.stance = stance
	var hand := PunchController.hand_for(row.move, stance)
	var offset := PunchSpec.default_target_offset()
	offset.x = SIDE_M if hand == &"left" else -SIDE_M
	if row.sandbag != null:
		row.sandbag.queue_free()
	var sandbag: Node3D = SANDBAG_SCENE.instantiate()
	sandbag.position = row.origin + offset
	add_child(sandbag)
	row.sandbag = sandbag
	row.bag = sandbag.get_node("Bag")
	controller.target = row.bag
	var stance_name := "orthodox" if stance == PunchController.ORTHODOX else "southpaw"
	row.label.text = "%d %s\n%s\n%s hand" % [MOVES.find(row.move) + 1, String(row.move).replace("_", " "), stance_name, hand]
	controller.punch(row.move)
