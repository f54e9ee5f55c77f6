## A bout: the own-character demo's two fighters (a 1.90 m orthodox and a 1.60 m southpaw, converted CC0 MakeHuman
## characters driven through a PunchSkeletonModifier each) trade strings of punches at each other's head and body,
## block and take hits, for a minute. Each is run by a small scripted AI, the game's part (nothing here is learned):
##
## - every 0.5-1.4 s, when it is neither punching, blocking nor down, it throws one of `STRINGS` (boxing's numbers:
##   1-2, 1-2-3, 2-3-2, 1-1-2, 1-2-5-2, 3-6) with `combo()`, at the opponent's head (three times in five) or body,
##   among those whose every move reaches it from where the fighter stands (`reaches(move, position)`; a jab and a
##   cross when none does);
## - when a punch of the opponent's starts and it is not punching, every other time it raises its guard `REACTION_S`
##   later with `block(BLOCK_S)`;
## - knocked down (it is not, at these punches' strength), it gets up `GET_UP_S` later with `recover()`.
##
## The controllers do the rest: a hit ends the punch it strikes and drives the body back to guard, the head snaps
## on its neck, a punch says whether it landed, was blocked or whiffed. The label shows each fighter's count.
## Make the characters first (see own_character.gd). `-- --seconds=S` fights S seconds, prints `BOUT <json>` (per
## fighter: strings and punches thrown, each outcome, the parts its fists struck, blocks raised, hits taken) and
## quits; without it the bout starts again every minute.
extends "res://demo/own_character.gd"

## The strings each AI picks from.
const STRINGS: Array = [[&"jab", &"cross"], [&"jab", &"cross", &"lead_hook"], [&"cross", &"lead_hook", &"cross"],
	[&"jab", &"jab", &"cross"], [&"jab", &"cross", &"lead_uppercut", &"cross"], [&"lead_hook", &"rear_uppercut"]]
## Seconds between one decision and the next: the shortest and the longest.
const THINK_S := Vector2(0.5, 1.4)
## Share of the opponent's punches blocked (when not punching), seconds from the punch's start to the guard rising,
## and how long the guard stays up.
const BLOCK_CHANCE := 0.5
const REACTION_S := 0.08
const BLOCK_S := 0.6
## Share of strings thrown at the head (the rest at the body), and seconds a knocked-down fighter stays down.
const HEAD_SHARE := 0.6
const GET_UP_S := 1.5
const ROUND_S := 60.0

var _rng := RandomNumberGenerator.new()
var _frame := 0
var _seconds := 0.0


func _ready() -> void:
	_rng.seed = 11
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--characters="):
			_characters_dir = argument.trim_prefix("--characters=")
		elif argument.begins_with("--seconds="):
			_seconds = float(argument.trim_prefix("--seconds="))
	add_child(_timer)  # own_character.gd's, unused here: in the tree, it is freed with the scene
	build_stage(Vector3(3.2, 1.5, 0.1))
	var camera := get_viewport().get_camera_3d()
	camera.fov = 38.0
	camera.look_at_from_position(Vector3(2.6, 1.55, 0.4), Vector3(0.0, 1.2, 0.4))
	var places := [Transform3D.IDENTITY, Transform3D(Basis(Vector3.UP, PI), Vector3(0, 0, SPARRING_DISTANCE_M))]
	for index in FIGHTERS.size():
		var rig := _load_character(FIGHTERS[index])
		if rig == null:
			return
		_fighters.append(_add_boxer(FIGHTERS[index], rig, places[index], index))
	for index in _fighters.size():
		var me: Dictionary = _fighters[index]
		var opponent: Dictionary = _fighters[1 - index]
		me.opponent = opponent
		opponent.controller.punch_started.connect(func(_move, _hand, _combo_index):
			if not me.busy and me.block_at < _frame and _rng.randf() < BLOCK_CHANCE:
				me.block_at = _frame + roundi(REACTION_S * Engine.physics_ticks_per_second))
		me.next_think_at = _frame + _think_frames()


## A fighter as own_character.gd adds one (`_add_rigged`), with the counts and the AI's state the bout keeps.
func _add_boxer(file: String, rig: Node3D, place: Transform3D, index: int) -> Dictionary:
	var fighter := _add_rigged(file, rig, place, index)
	var controller: PunchController = fighter.controller
	var character: Node3D = fighter.character
	fighter.merge({"stance": "orthodox" if index == 0 else "southpaw", "busy": false, "block_at": -1, "get_up_at": -1,
		"next_think_at": 0, "strings": 0, "punches": 0, "landed": 0, "blocked": 0, "whiffed": 0, "struck": {},
		"blocks": 0, "hits_taken": 0, "knocked_down": 0})
	controller.punch_started.connect(func(_move, _hand, _combo_index): fighter.busy = true)
	controller.punch_finished.connect(func(metrics: Dictionary):
		fighter.punches += 1
		fighter[metrics.outcome] += 1
		_show())
	controller.combo_finished.connect(func(_landed, _thrown): fighter.busy = false)
	controller.hit.connect(func(_impulse, _speed, _position, _body, _push, _hand, part: StringName, _blocked):
		if part != &"":
			fighter.struck[part] = fighter.struck.get(part, 0) + 1)
	character.hit_taken.connect(func(_part, _impulse, _point, _from, _bone): fighter.hits_taken += 1)
	controller.knocked_down.connect(func(_impulse_ns):
		fighter.knocked_down += 1
		fighter.get_up_at = _frame + roundi(GET_UP_S * Engine.physics_ticks_per_second))
	return fighter


func _think_frames() -> int:
	return roundi(_rng.randf_range(THINK_S.x, THINK_S.y) * Engine.physics_ticks_per_second)


func _physics_process(delta: float) -> void:
	super(delta)
	if _fighters.size() < 2:
		return
	_frame += 1
	for fighter in _fighters:
		var controller: PunchController = fighter.controller
		if fighter.get_up_at == _frame:
			controller.recover()
		if fighter.block_at == _frame and not fighter.busy and not controller.is_knocked_down():
			controller.block(BLOCK_S)
			fighter.blocks += 1
		if _frame >= fighter.next_think_at:
			fighter.next_think_at = _frame + _think_frames()
			if not (fighter.busy or controller.is_blocking() or controller.is_knocked_down()):
				_throw(fighter)
	var limit := _seconds if _seconds > 0.0 else ROUND_S
	if _frame == roundi(limit * Engine.physics_ticks_per_second):
		_end_round()


## The AI's string: one of `STRINGS` whose every move reaches the target from where the fighter stands
## (`reaches(move, position)`, the rule `punch()` checks: a hook or an uppercut is a close punch, and a short-armed
## rig reaches less far), at the opponent's head or body; a jab and a cross when none does.
func _throw(fighter: Dictionary) -> void:
	var controller: PunchController = fighter.controller
	var opponent: Node3D = fighter.opponent.character
	var target: Node3D = opponent.get_node("Head" if _rng.randf() < HEAD_SHARE else "Torso")
	controller.target = target
	var fitting := STRINGS.filter(func(moves: Array) -> bool:
		return moves.all(func(move: StringName) -> bool: return controller.reaches(move, target.global_position)))
	var index := _rng.randi_range(0, maxi(fitting.size() - 1, 0))
	if controller.combo(fitting[index] if not fitting.is_empty() else [&"jab", &"cross"]):
		fighter.strings += 1
		fighter.busy = true



func _show() -> void:
	var lines := []
	for fighter in _fighters:
		lines.append("%s (%s): %d punches, %d landed, %d blocked, %d whiffed; %d blocks raised" % [fighter.name,
			fighter.stance, fighter.punches, fighter.landed, fighter.blocked, fighter.whiffed, fighter.blocks])
	_label.text = "\n".join(lines)


func _end_round() -> void:
	var report := []
	for fighter in _fighters:
		report.append({"name": fighter.name, "stance": fighter.stance, "mapped": fighter.modifier.is_mapped(),
			"strings": fighter.strings, "punches": fighter.punches, "landed": fighter.landed,
			"blocked": fighter.blocked, "whiffed": fighter.whiffed, "struck": fighter.struck, "blocks": fighter.blocks,
			"hits_taken": fighter.hits_taken, "knocked_down": fighter.knocked_down})
	print("BOUT ", JSON.stringify(report))
	if _seconds > 0.0:
		get_tree().quit(0)
		return
	_frame = 0
	for fighter in _fighters:
		for key in ["strings", "punches", "landed", "blocked", "whiffed", "blocks", "hits_taken", "knocked_down"]:
			fighter[key] = 0
		fighter.struck = {}
		fighter.next_think_at = _think_frames()
