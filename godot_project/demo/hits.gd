## Taking hits: three characters in guard, each struck by the game (`PunchCharacter.take_hit`) every two seconds from
## the front, 30, 60 and 320 N s on the chest: the first gives way and comes back, the second staggers, the third is
## knocked down and hangs limp until the demo calls `recover()` a second later. A red ball marks where each hit lands;
## above each character, its last `hit_taken` and what its controller said. Prints `HITS_DEMO <json>` (how many of each
## signal) after `--rounds=N` rounds when given.
extends "res://demo/arena.gd"

const IMPULSES_NS: Array[float] = [30.0, 60.0, 320.0]
const EVERY_S := 2.0
const GET_UP_AFTER_S := 1.0

var _rows: Array[Dictionary] = []
var _rounds_wanted := 0
var _rounds := 0
var _clock := 0.0


func _ready() -> void:
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--rounds="):
			_rounds_wanted = int(argument.trim_prefix("--rounds="))
	# Seen from the front, a little from the characters' right: each pushed back, away from the camera.
	build_stage(Vector3(-1.2, 1.6, 3.0))
	add_sky(self)
	for index in IMPULSES_NS.size():
		var where := Transform3D(Basis.IDENTITY, Vector3(1.6 * index - 1.6, 0, 0))
		var character := add_character(self, where)
		var controller := add_controller(character, null, 0.0, index + 1)
		var row := {"character": character, "controller": controller, "impulse_ns": IMPULSES_NS[index],
			"label": add_label_above(where.origin, true), "said": "",
			"counts": {"hit_taken": 0, "staggered": 0, "knocked_down": 0, "recovered": 0}}
		character.hit_taken.connect(func(part, impulse: Vector3, _point, _from, _bone):
			row.counts.hit_taken += 1
			row.said = "%s, %d N s" % [part, roundi(impulse.length())]
			_show(row))
		controller.staggered.connect(func(_impulse_ns):
			row.counts.staggered += 1
			row.said += "\nstaggered"
			_show(row))
		controller.knocked_down.connect(func(_impulse_ns):
			row.counts.knocked_down += 1
			row.said += "\nknocked down"
			_show(row)
			get_tree().create_timer(GET_UP_AFTER_S, true, true).timeout.connect(func(): controller.recover()))
		controller.recovered.connect(func():
			row.counts.recovered += 1
			row.said += "\nback in guard"
			_show(row))
		_rows.append(row)


func _physics_process(delta: float) -> void:
	_clock += delta
	if _clock < EVERY_S:
		return
	_clock = 0.0
	if _rounds_wanted > 0 and _rounds == _rounds_wanted:
		var counts := {}
		for row in _rows:
			counts["%d N s" % roundi(row.impulse_ns)] = row.counts
		print("HITS_DEMO ", JSON.stringify(counts))
		get_tree().quit()
		return
	_rounds += 1
	for row in _rows:
		var character: Node3D = row.character
		var point: Vector3 = character.get_node("Torso").global_position + Vector3.UP * 0.15
		character.take_hit(&"torso", -character.global_basis.z * row.impulse_ns, point)
		_mark(point)


## A red ball where a hit landed, for a moment.
func _mark(point: Vector3) -> void:
	var ball := MeshInstance3D.new()
	var sphere := SphereMesh.new()
	sphere.radius = 0.06
	sphere.height = 0.12
	var material := StandardMaterial3D.new()
	material.albedo_color = Color(0.9, 0.1, 0.1)
	sphere.material = material
	ball.mesh = sphere
	ball.position = point + Vector3(0, 0, 0.12)
	add_child(ball)
	get_tree().create_timer(0.3, true, true).timeout.connect(ball.queue_free)


func _show(row: Dictionary) -> void:
	(row.label as Label3D).text = "%d N s\n%s" % [roundi(row.impulse_ns), row.said]
