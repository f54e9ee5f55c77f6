## A bout: the own-character demo's two fighters (a 1.90 m orthodox and a 1.60 m southpaw, converted CC0 MakeHuman
## characters driven through a PunchSkeletonModifier each) trade strings of punches at each other's head and body,
## block and take hits, for a minute. Each is run by a small scripted AI, the game's part (nothing here is learned):
##
## - every 0.5-1.4 s, when it is neither punching, blocking nor down, it picks one of `STRINGS` (boxing's numbers:
##   1-2, 1-2-3, 2-3-2, 1-1-2, 1-2-5-2, 3-6) at the opponent's head (three times in five) or body, and throws it with
##   `combo()` when every move of it reaches from where the fighter stands (`reaches(move, position)`); when a step
##   nearer would bring it in reach (a hook or an uppercut is a close punch), it first steps in at `STEP_MPS`, at most
##   `STEP_IN_S` and to `CLOSEST_M`; else it throws a string that reaches now, a jab and a cross when none does;
## - between strings it steps back out to `APART_M` (`-- --apart=M` sets it: farther apart, more strings need a step in);
## - when a punch of the opponent's starts and it is not punching, every other time it raises its guard `REACTION_S`
##   later with `block(BLOCK_S)`;
## - knocked down (it is not, at these punches' strength), it gets up `GET_UP_S` later with `recover()`.
##
## A step moves the rig (the root the game owns); the modifier carries the simulated body with it. The controllers do
## the rest: a hit ends the punch it strikes and drives the body back to guard, the head snaps on its neck, a punch
## says whether it landed, was blocked or whiffed. The label shows each fighter's count.
## Make the characters first (see own_character.gd). `-- --seconds=S` fights S seconds, prints `BOUT <json>` (per
## fighter: strings and punches thrown, each outcome, the parts its fists struck, blocks raised, hits taken, steps in
## and how far apart the fighters stand at the end) and quits; without it the bout starts again every minute.
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
## Footwork: the walking speed of a step in or out (m/s), the distance kept between strings and the nearest the
## fighters come (m, root to root), and how long a fighter steps in for a string before it throws a jab and a cross.
const STEP_MPS := 0.7
const APART_M := SPARRING_DISTANCE_M
const CLOSEST_M := 0.55
const STEP_IN_S := 1.0

var _rng := RandomNumberGenerator.new()
var _frame := 0
var _seconds := 0.0
## The distance kept between strings (m, root to root): `APART_M` unless `--apart=M` says otherwise.
var _apart_m := APART_M


func _ready() -> void:
	_rng.seed = 11
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--characters="):
			_characters_dir = argument.trim_prefix("--characters=")
		elif argument.begins_with("--seconds="):
			_seconds = float(argument.trim_prefix("--seconds="))
		elif argument.begins_with("--apart="):
			_apart_m = maxf(float(argument.trim_prefix("--apart=")), CLOSEST_M)
	add_child(_timer)  # own_character.gd's, unused here: in the tree, it is freed with the scene
	build_stage(Vector3(3.2, 1.5, 0.1))
	var camera := get_viewport().get_camera_3d()
	camera.fov = 38.0
	camera.look_at_from_position(Vector3(2.6, 1.55, 0.4), Vector3(0.0, 1.2, 0.4))
	var places := [Transform3D.IDENTITY, Transform3D(Basis(Vector3.UP, PI), Vector3(0, 0, _apart_m))]
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
		"next_think_at": 0, "plan": [], "plan_target": null, "plan_until": -1, "steps_in": 0, "strings": 0,
		"punches": 0, "landed": 0, "blocked": 0, "whiffed": 0, "struck": {},
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
		var free: bool = not (fighter.busy or controller.is_blocking() or controller.is_knocked_down())
		if not free:
			fighter.plan = []
		elif not fighter.plan.is_empty():
			_step_in_or_throw(fighter, delta)
		elif _frame >= fighter.next_think_at:
			fighter.next_think_at = _frame + _think_frames()
			_plan(fighter)
		elif _apart(fighter) < _apart_m - 0.01:
			_step(fighter, -STEP_MPS * delta)
	var limit := _seconds if _seconds > 0.0 else ROUND_S
	if _frame == roundi(limit * Engine.physics_ticks_per_second):
		_end_round()


## The AI's next string: one of `STRINGS` at the opponent's head or body. Thrown now when every move of it reaches
## the target from here (`reaches(move, position)`, the rule `punch()` checks: a hook or an uppercut is a close
## punch, and a short-armed rig reaches less far); when it would reach from a step nearer, the fighter steps in first;
## else it throws one of the strings that reach now, a jab and a cross when none does.
func _plan(fighter: Dictionary) -> void:
	var opponent: Node3D = fighter.opponent.character
	var target: Node3D = opponent.get_node("Head" if _rng.randf() < HEAD_SHARE else "Torso")
	var string: Array = STRINGS[_rng.randi_range(0, STRINGS.size() - 1)]
	var step_m := _step_to_reach(fighter, string, target)
	if step_m > 0.0:
		fighter.merge({"plan": string, "plan_target": target, "steps_in": fighter.steps_in + 1,
			"plan_until": _frame + roundi(STEP_IN_S * Engine.physics_ticks_per_second)}, true)
		return
	if step_m < 0.0:
		var fitting := STRINGS.filter(func(moves: Array) -> bool: return _reaches(fighter, moves, target.global_position))
		string = fitting[_rng.randi_range(0, fitting.size() - 1)] if not fitting.is_empty() else [&"jab", &"cross"]
	_throw(fighter, string, target)


## Steps in until the planned string reaches, then throws it; a jab and a cross when the fighters are as near as they
## come or it stepped in `STEP_IN_S` (the opponent moved too).
func _step_in_or_throw(fighter: Dictionary, delta: float) -> void:
	var target: Node3D = fighter.plan_target
	if _reaches(fighter, fighter.plan, target.global_position):
		_throw(fighter, fighter.plan, target)
	elif _apart(fighter) <= CLOSEST_M + 0.005 or _frame >= fighter.plan_until:
		_throw(fighter, [&"jab", &"cross"], target)
	else:
		_step(fighter, STEP_MPS * delta)


func _throw(fighter: Dictionary, string: Array, target: Node3D) -> void:
	fighter.plan = []
	fighter.controller.target = target
	if fighter.controller.combo(string):
		fighter.strings += 1
		fighter.busy = true


## How far the fighter must step toward its opponent for every move of `string` to reach `target`: 0 when they reach
## from here, -1 when no step down to `CLOSEST_M` brings them all in reach (the target too high or low for them).
func _step_to_reach(fighter: Dictionary, string: Array, target: Node3D) -> float:
	var toward: Vector3 = fighter.opponent.rig.global_position - fighter.rig.global_position
	toward.y = 0.0
	var step_m := 0.0
	while step_m <= _apart(fighter) - CLOSEST_M:
		# Stepping in by step_m brings the target that much nearer along the line between the fighters.
		var seen_at: Vector3 = target.global_position - toward.normalized() * step_m
		if _reaches(fighter, string, seen_at):
			return step_m
		step_m += 0.02
	return -1.0


## Whether every move of `string` reaches a target at `position` from where the fighter stands.
func _reaches(fighter: Dictionary, string: Array, position: Vector3) -> bool:
	var controller: PunchController = fighter.controller
	return string.all(func(move: StringName) -> bool: return controller.reaches(move, position))


## How far apart the two fighters' roots stand (m, on the floor).
func _apart(fighter: Dictionary) -> float:
	var me: Vector3 = fighter.rig.global_position
	var other: Vector3 = fighter.opponent.rig.global_position
	return Vector2(me.x - other.x, me.z - other.z).length()


## Moves the fighter's rig `distance_m` toward its opponent (negative: away), never nearer than `CLOSEST_M` nor, going
## away, farther than `_apart_m`.
func _step(fighter: Dictionary, distance_m: float) -> void:
	var me: Node3D = fighter.rig
	var other: Vector3 = fighter.opponent.rig.global_position
	var toward := Vector3(other.x - me.global_position.x, 0.0, other.z - me.global_position.z)
	var apart := toward.length()
	if apart < 1e-3:
		return
	me.global_position += toward / apart * clampf(distance_m, minf(0.0, apart - _apart_m), maxf(0.0, apart - CLOSEST_M))



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
			"hits_taken": fighter.hits_taken, "knocked_down": fighter.knocked_down, "steps_in": fighter.steps_in,
			"apart_m": snappedf(_apart(fighter), 0.01)})
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
