## Combinations: three characters at their sandbags, each throwing boxing's combinations in turn (1-2, 1-2-3, 2-3-2,
## 1-1-2, 1-2-5-2) with one `combo()` call, from the addon's moveset; each punch starts at the one before's contact
## (its cancel window). After every combination the stance flips. Above each character: the combination, each punch as
## it lands (a tick) or misses, and `combo_finished`'s count. Prints the share of punches that hit (`--punches=N`).
extends "res://demo/arena.gd"

const COMBOS: Array = [
	["1-2", [&"jab", &"cross"]],
	["1-2-3", [&"jab", &"cross", &"lead_hook"]],
	["2-3-2", [&"cross", &"lead_hook", &"cross"]],
	["1-1-2", [&"jab", &"jab", &"cross"]],
	["1-2-5-2", [&"jab", &"cross", &"lead_uppercut", &"cross"]],
]
const SANDBAG_SCENE := preload("res://addons/punch_controller/scenes/punch_sandbag.tscn")


func _ready() -> void:
	# Seen from the characters' right, a little ahead: each character and its bag in profile.
	build_stage(Vector3(-3.7, 2.0, 1.3))
	add_sky(self)
	for index in 3:
		var where := Transform3D(Basis.IDENTITY, Vector3(0, 0, 2.4 * index - 2.4))
		var character := add_character(self, where)
		var controller := add_controller(character, null, 0.1, index + 1)
		var label := add_label_above(where.origin, true)
		var row := {"controller": controller, "sandbag": null, "bag": null, "origin": where.origin, "label": label,
			"combo": index, "title": "", "marks": [],
			"landed": false}
		controller.punch_started.connect(func(move, _hand, _combo_index):
			row.marks.append("%d" % _number_of(move))
			row.landed = false
			_show(row))
		controller.hit.connect(func(_impulse, _speed, _position, body, _push, _hand, _part, _blocked):
			row.landed = row.landed or body == row.bag)
		controller.punch_finished.connect(func(_metrics):
			row.marks[-1] += " ✓" if row.landed else " ✗"
			count_punch(row.landed, "combos")
			_show(row))
		controller.combo_finished.connect(func(landed, thrown):
			row.title += "  %d of %d" % [landed, thrown]
			if "--verbose" in OS.get_cmdline_user_args():
				print("COMBO ", row.title, " ", row.marks)
			_show(row))
		controller.recovered.connect(func(): _throw(row))
		_throw.call_deferred(row)


## The next combination of the row, in the other stance, at a new sandbag hanging at rest in front of both hands
## (its rope's hook is fixed where it is made, so the old one goes).
func _throw(row: Dictionary) -> void:
	var controller: PunchController = row.controller
	if row.sandbag != null:
		row.sandbag.queue_free()
	var sandbag: Node3D = SANDBAG_SCENE.instantiate()
	var offset := PunchSpec.default_target_offset()
	offset.x = 0.0
	sandbag.position = row.origin + offset
	add_child(sandbag)
	row.sandbag = sandbag
	row.bag = sandbag.get_node("Bag")
	controller.target = row.bag
	var combo: Array = COMBOS[row.combo % COMBOS.size()]
	controller.stance = PunchController.ORTHODOX if row.combo % 2 == 0 else PunchController.SOUTHPAW
	row.combo += 1
	row.title = "%s, %s" % [combo[0], "orthodox" if controller.stance == PunchController.ORTHODOX else "southpaw"]
	row.marks = []
	controller.combo(combo[1])


func _number_of(move: StringName) -> int:
	return [&"jab", &"cross", &"lead_hook", &"rear_hook", &"lead_uppercut", &"rear_uppercut"].find(move) + 1


func _show(row: Dictionary) -> void:
	row.label.text = "%s\n%s" % [row.title, "  ".join(row.marks)]
