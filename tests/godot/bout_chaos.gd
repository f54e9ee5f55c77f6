## Pairs of characters facing each other, each controller punching its opponent's head or torso at random times with random
## moves and combinations (the addon's moveset, random stance and noise), cancelling and recovering at random, while
## the game strikes random parts at random strengths (`take_hit`, up to knock-downs, after which it calls `recover()`
## some time later). Every promise is checked as the signals come: each `punch_started` gets exactly one
## `punch_finished`, with an `ended` and an `outcome` it knows; `hit_taken` names a part and its source; a knocked-down
## controller says so until it is brought back. Every second the bodies are checked: finite, near their character,
## above the floor. Every `--sample-s` seconds (10) the run notes the process's memory (Godot's own allocations, and
## all of it resident), the engine's objects and nodes,
## and the physics frame's cost (all of it, and the controllers' part): a long run (`punch bench soak`: 20 pairs for
## 10 minutes) shows whether they stay flat. Prints `BOUT_CHAOS <json>` and quits. Options: --seed=N --seconds=S
## --pairs=N --sample-s=S.
extends SceneTree

const CHARACTER_SCENE := preload("res://addons/punch_controller/scenes/punch_character.tscn")
const POLICY := "res://addons/punch_controller/policies/straight.onnx"
const MOVES := [&"jab", &"cross", &"lead_hook", &"rear_hook", &"lead_uppercut", &"rear_uppercut"]
const PARTS := [&"head", &"torso", &"left_arm", &"right_arm"]
const ENDINGS := ["completed", "interrupted", "chained", "struck"]
const OUTCOMES := ["landed", "blocked", "whiffed"]
const BODIES := ["Torso", "UpperArmR", "ForearmR", "UpperArmL", "ForearmL", "Head"]


## One fighter and what its listener has heard.
class Fighter:
	var character: Node3D
	var controller: PunchController
	var opponent: Node3D
	var punch_open := false
	var started := 0
	var finished := 0
	var endings := {}
	var outcomes := {}
	var hits_taken := 0
	var knocked_down := 0
	var get_up_at := -1


var _options := {"seed": "1", "seconds": "30", "pairs": "10", "sample-s": "10"}
var _rng := RandomNumberGenerator.new()
var _fighters: Array[Fighter] = []
var _frame := 0
var _problems: Array = []
var _calls := 0
var _game_hits := 0
var _samples: Array = []
var _frame_usec := 0
var _frames_timed := 0
var _last_frame_at := -1


func _initialize() -> void:
	for argument in OS.get_cmdline_user_args():
		var parts := argument.trim_prefix("--").split("=", true, 1)
		if parts.size() == 2 and _options.has(parts[0]):
			_options[parts[0]] = parts[1]
	_rng.seed = int(_options.seed)
	var distance := PunchSpec.default_target_offset().z
	for pair in int(_options.pairs):
		var origin := Vector3(4.0 * pair, 0, 0)
		var a := _add_fighter(Transform3D(Basis.IDENTITY, origin), pair * 2)
		var b := _add_fighter(Transform3D(Basis(Vector3.UP, PI), origin + Vector3(0, 0, distance)), pair * 2 + 1)
		a.opponent = b.character
		b.opponent = a.character
		a.controller.target = b.character.get_node("Torso")
		b.controller.target = a.character.get_node("Torso")


func _add_fighter(where: Transform3D, index: int) -> Fighter:
	var fighter := Fighter.new()
	fighter.character = CHARACTER_SCENE.instantiate()
	fighter.character.transform = where
	root.add_child(fighter.character)
	fighter.controller = PunchController.new()
	fighter.controller.character = fighter.character
	fighter.controller.policy = load(POLICY)
	fighter.controller.stance = _rng.randi_range(0, 1)
	fighter.controller.noise_sigma = _rng.randf_range(0.0, 0.3)
	fighter.controller.seed = index
	fighter.controller.hyper_armour = _rng.randf() < 0.2
	root.add_child(fighter.controller)
	var controller := fighter.controller
	controller.punch_started.connect(func(_move, _hand, _combo_index):
		if fighter.punch_open:
			_problem(fighter, "a punch started before the last one finished")
		fighter.punch_open = true
		fighter.started += 1)
	controller.punch_finished.connect(func(metrics: Dictionary):
		if not fighter.punch_open:
			_problem(fighter, "a finish with no punch")
		fighter.punch_open = false
		fighter.finished += 1
		if not metrics.ended in ENDINGS or not metrics.outcome in OUTCOMES:
			_problem(fighter, "a finish that says %s / %s" % [metrics.ended, metrics.outcome])
		fighter.endings[metrics.ended] = fighter.endings.get(metrics.ended, 0) + 1
		fighter.outcomes[metrics.outcome] = fighter.outcomes.get(metrics.outcome, 0) + 1
		if _rng.randf() < 0.1 and not fighter.controller.is_knocked_down():
			_command(fighter))  # a game that answers inside the handler
	fighter.character.hit_taken.connect(func(part, impulse: Vector3, point: Vector3, from, _bone):
		fighter.hits_taken += 1
		if not part in PARTS or not impulse.is_finite() or not point.is_finite():
			_problem(fighter, "hit_taken says %s %s %s" % [part, impulse, point])
		if from != null and not from is PunchController:
			_problem(fighter, "hit_taken from %s" % from)
		if _rng.randf() < 0.1 and not fighter.controller.is_knocked_down():
			_command(fighter))
	controller.knocked_down.connect(func(_impulse_ns):
		fighter.knocked_down += 1
		if fighter.punch_open:
			_problem(fighter, "knocked down with a punch open")
		fighter.get_up_at = _frame + _rng.randi_range(30, 240))
	_fighters.append(fighter)
	return fighter


func _physics_process(_delta: float) -> bool:
	_frame += 1
	# Headless with --fixed-fps, frames run back to back: the wall time between two is one frame's whole cost.
	var now := Time.get_ticks_usec()
	if _last_frame_at >= 0:
		_frame_usec += now - _last_frame_at
		_frames_timed += 1
	_last_frame_at = now
	if _frame % roundi(float(_options["sample-s"]) * Engine.physics_ticks_per_second) == 0:
		_sample()
	var seconds := float(_options.seconds)
	if _frame <= roundi(seconds * Engine.physics_ticks_per_second):
		for fighter in _fighters:
			if fighter.get_up_at == _frame:
				if not fighter.controller.is_knocked_down():
					_problem(fighter, "up again before the game said so")
				fighter.controller.recover()
			if _rng.randf() < 0.02 and not fighter.controller.is_knocked_down():  # down: the game waits to bring it back
				_command(fighter)
			if _rng.randf() < 0.002:
				_strike(fighter)
		if _frame % Engine.physics_ticks_per_second == 0:
			for fighter in _fighters:
				_check_bodies(fighter)
		return false
	if _frame < roundi(seconds * Engine.physics_ticks_per_second) + 600:  # quiet: everything that runs ends
		return false
	for fighter in _fighters:
		if fighter.punch_open or fighter.started != fighter.finished:
			_problem(fighter, "%d started, %d finished" % [fighter.started, fighter.finished])
		_check_bodies(fighter)
	var report := {"problems": _problems.slice(0, 10), "problem_count": _problems.size(), "calls": _calls,
		"game_hits": _game_hits, "fighters": [], "samples": _samples}
	for fighter in _fighters:
		report.fighters.append({"started": fighter.started, "finished": fighter.finished, "endings": fighter.endings,
			"outcomes": fighter.outcomes, "hits_taken": fighter.hits_taken, "knocked_down": fighter.knocked_down})
	print("BOUT_CHAOS ", JSON.stringify(report))
	quit(0)
	return true


## A random command, as a game's AI or a player gives it.
func _command(fighter: Fighter) -> void:
	_calls += 1
	var roll := _rng.randf()
	fighter.controller.target = fighter.opponent.get_node("Head" if _rng.randf() < 0.5 else "Torso")
	if roll < 0.55:
		fighter.controller.punch(MOVES[_rng.randi_range(0, MOVES.size() - 1)])
	elif roll < 0.8:
		var moves := []
		for _i in _rng.randi_range(2, 3):
			moves.append(MOVES[_rng.randi_range(0, MOVES.size() - 1)])
		fighter.controller.combo(moves)
	elif roll < 0.9:
		fighter.controller.cancel()
	else:
		fighter.controller.recover()


## The game's own hit: a random part, direction and strength (a tenth of them knock-downs).
func _strike(fighter: Fighter) -> void:
	_game_hits += 1
	var part: StringName = PARTS[_rng.randi_range(0, PARTS.size() - 1)]
	var at := {&"head": "Head/HeadMesh", &"torso": "Torso", &"left_arm": "ForearmL", &"right_arm": "ForearmR"}
	var point: Vector3 = fighter.character.get_node(at[part]).global_position
	var direction := Vector3(_rng.randf_range(-1, 1), _rng.randf_range(-0.3, 0.3), _rng.randf_range(-1, 1)).normalized()
	var strength := _rng.randf_range(320.0, 400.0) if _rng.randf() < 0.1 else _rng.randf_range(1.0, 120.0)
	if not fighter.character.take_hit(part, direction * strength, point):
		_problem(fighter, "a hit refused")


## Where the run stands: seconds played, the process's memory (MB), the engine's objects and nodes, and the mean cost
## of a frame since the last sample (µs: the whole frame, physics and all, and the controllers' part).
func _sample() -> void:
	_samples.append({"s": float(_frame) / Engine.physics_ticks_per_second,
		"memory_mb": snappedf(OS.get_static_memory_usage() / 1048576.0, 0.01), "rss_mb": _resident_mb(),
		"objects": int(Performance.get_monitor(Performance.OBJECT_COUNT)),
		"nodes": int(Performance.get_monitor(Performance.OBJECT_NODE_COUNT)),
		"frame_usec": snappedf(float(_frame_usec) / maxi(_frames_timed, 1), 0.1),
		"controllers_usec": snappedf(PunchProbe.take_frame_cost_usec(), 0.1)})
	_frame_usec = 0
	_frames_timed = 0


## The process's resident memory (MB: Godot's, the extension's and ONNX Runtime's alike), from Linux's
## /proc/self/status; -1 elsewhere.
func _resident_mb() -> float:
	var status := FileAccess.open("/proc/self/status", FileAccess.READ)  # its length reads 0: read it line by line
	while status != null and not status.eof_reached():
		var line := status.get_line()
		if line.begins_with("VmRSS:"):
			return snappedf(float(line.split(":")[1].strip_edges().split(" ")[0]) / 1024.0, 0.1)
		if line.is_empty():
			break
	return -1.0


## Every body finite, within 1.2 m of its character's chest height and above the floor.
func _check_bodies(fighter: Fighter) -> void:
	var chest := fighter.character.global_position + Vector3.UP * 1.3
	for body in BODIES:
		var place: Vector3 = fighter.character.get_node(body).global_position
		if not place.is_finite() or place.distance_to(chest) > 1.2 or place.y < 0.0:
			_problem(fighter, "%s at %s" % [body, place])


func _problem(fighter: Fighter, what: String) -> void:
	_problems.append("%s, frame %d: %s" % [fighter.controller.name, _frame, what])
