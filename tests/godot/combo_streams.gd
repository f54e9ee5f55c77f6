## Random command streams against the combo promises, as games send them: 16 characters with the addon's moveset, each
## getting random `punch(move)`, `combo([...])`, `cancel()` and `recover()` calls at random frames and, with some odds,
## inside its own `punch_started`, `hit`, `punch_finished` and `combo_finished` handlers; then every stream goes quiet
## and the frames run on. Checked as each signal comes (a broken promise is recorded with the stream's last events):
## every `punch_started` is followed by exactly one `punch_finished`; a punch's `combo_index` is 0 or one more than the
## punch before it, whose end was "chained" or "completed"; one `combo_finished` follows a string's last finish, its
## `thrown` the string's length; and each queued move (`queued_moves()` after every call) starts once, in order,
## unless a later call, `cancel()` or `recover()` dropped it. Prints `COMBO_STREAMS <json>`.
## Options: --seed=N --frames=N (commands for that many frames, then 600 quiet ones).
extends SceneTree

const PunchPair := preload("res://tools/punch_pair.gd")
const POLICY := "res://addons/punch_controller/policies/straight.onnx"
const MOVES := [&"jab", &"cross", &"lead_hook", &"rear_hook", &"lead_uppercut", &"rear_uppercut"]
const STREAMS := 16
const QUIET_FRAMES := 600


## One controller's stream and what its listener has heard.
class Stream:
	var controller: Node
	var punch_open := false
	## The open string's last punch index (-1: no string open).
	var last_index := -1
	## The moves the game queued that have not started yet, as the listener expects them.
	var waiting: Array = []
	## The last punch ended chained: its successor's start must come next.
	var chained := false
	## That successor's move (it left the queue when the punch before it ended).
	var successor := &""
	## What waited when the last punch finished, before its handlers ran (a string ends then or never).
	var waiting_at_finish: Array = []
	var started := 0
	var finished := 0
	var strings := 0
	var combos_finished := 0
	var chained_starts := 0
	var history: Array = []


var _options := {"seed": "1", "frames": "2400"}
var _rng := RandomNumberGenerator.new()
var _streams: Array[Stream] = []
var _frame := 0
var _problems: Array = []
var _calls := 0
var _handler_calls := 0


func _initialize() -> void:
	var error := PunchPair.read_options(_options)
	if error != "":
		printerr(error)
		quit(2)
		return
	_rng.seed = int(_options.seed)
	var arena: SubViewport
	for index in STREAMS:
		if index % PunchPair.MAX_PER_WORLD == 0:
			arena = PunchPair.add_arena(root)
		var stream := Stream.new()
		var bag_offset := PunchSpec.default_target_offset()
		bag_offset.x = 0.0  # in front of both hands
		stream.controller = PunchPair.add(arena, index % PunchPair.MAX_PER_WORLD, Vector3.ZERO, bag_offset, POLICY,
			0.3, -1, index)
		_listen(stream)
		_streams.append(stream)


func _physics_process(_delta: float) -> bool:
	_frame += 1
	var commanding := _frame <= int(_options.frames)
	if commanding:
		for stream in _streams:
			if _rng.randf() < 0.03:
				_command(stream)
	if _frame < int(_options.frames) + QUIET_FRAMES:
		return false
	var report := {"calls": _calls, "handler_calls": _handler_calls, "problems": _problems.slice(0, 5),
		"problem_count": _problems.size(), "streams": []}
	for stream in _streams:
		if stream.punch_open or stream.last_index >= 0 or not stream.waiting.is_empty() \
				or not (stream.controller.call("queued_moves") as PackedStringArray).is_empty():
			_problem(stream, "still busy after %d quiet frames" % QUIET_FRAMES)
		report.streams.append({"started": stream.started, "finished": stream.finished, "strings": stream.strings,
			"combos_finished": stream.combos_finished, "chained_starts": stream.chained_starts})
	report.problem_count = _problems.size()
	report.problems = _problems.slice(0, 5)
	print("COMBO_STREAMS ", JSON.stringify(report))
	quit(0)
	return true


## A random call a game makes, and what the listener then expects to wait.
func _command(stream: Stream) -> void:
	var controller := stream.controller
	var roll := _rng.randf()
	var moves: Array = []
	for _index in _rng.randi_range(1, 4):
		moves.append(MOVES[_rng.randi() % MOVES.size()])
	var queued_before := controller.call("queued_moves") as PackedStringArray
	var busy: bool = controller.call("is_punching") or not queued_before.is_empty()
	if roll < 0.45:
		moves.resize(1)
	# What waits after the call, set before it: its own signals' handlers (which may call again) come inside it.
	var before: Array = stream.waiting.duplicate()
	if roll < 0.8:
		stream.waiting = moves.duplicate() if busy else moves.slice(1)
		var thrown: bool = controller.call("combo", moves) if moves.size() > 1 else controller.call("punch", moves[0])
		if not thrown:
			_problem(stream, "refused %s" % [moves])
			stream.waiting = before
	else:
		# Both drop what waits (a string whose last punch has finished ends here).
		stream.waiting.clear()
		stream.waiting_at_finish.clear()
		controller.call("cancel" if roll < 0.9 else "recover")
	_calls += 1
	var queued := Array(controller.call("queued_moves") as PackedStringArray).map(func(m): return StringName(m))
	if queued != stream.waiting:
		_problem(stream, "queued %s, expected %s" % [queued, stream.waiting])
		stream.waiting = queued


func _listen(stream: Stream) -> void:
	var controller := stream.controller
	controller.connect("punch_started", func(move, _hand, combo_index):
		_hear(stream, "S%d:%s" % [combo_index, move])
		if stream.chained:
			stream.chained = false
		if stream.punch_open:
			_problem(stream, "a start before the last punch finished")
		stream.punch_open = true
		stream.started += 1
		if combo_index == 0:
			if stream.last_index >= 0:
				_problem(stream, "a new string before the last one finished")
			stream.strings += 1
		else:
			stream.chained_starts += 1
			if combo_index != stream.last_index + 1:
				_problem(stream, "punch %d after punch %d" % [combo_index, stream.last_index])
			var expected: StringName = stream.successor
			if expected == &"" and not stream.waiting.is_empty():
				expected = stream.waiting.pop_front()
			if expected != move:
				_problem(stream, "a chained %s where %s was queued" % [move, expected])
			stream.successor = &""
		stream.last_index = combo_index
		_maybe_command_in_handler(stream))
	controller.connect("hit", func(_impulse, _speed, _position, _body, _push, _hand, _part, _blocked):
		if stream.chained or not stream.punch_open:
			_problem(stream, "a hit outside a punch")
		_maybe_command_in_handler(stream))
	controller.connect("punch_finished", func(metrics: Dictionary):
		_hear(stream, "F:%s" % metrics.ended)
		if not stream.punch_open:
			_problem(stream, "a finish with no punch")
		stream.punch_open = false
		stream.finished += 1
		stream.chained = metrics.ended == "chained"
		if stream.chained:
			# Its successor has left the queue already: a handler's call here queues what follows it.
			if stream.waiting.is_empty():
				_problem(stream, "a punch chained with nothing queued")
			else:
				stream.successor = stream.waiting.pop_front()
		# An interrupted punch's string ends dropping what waited (the call that interrupted it, cancel() or
		# recover(), already told the listener; a handler may have queued a new string's moves since).
		stream.waiting_at_finish = [] if metrics.ended in ["interrupted", "error"] else stream.waiting.duplicate()
		_maybe_command_in_handler(stream))
	controller.connect("combo_finished", func(landed: int, thrown: int):
		_hear(stream, "C%d/%d" % [landed, thrown])
		if stream.punch_open or stream.chained:
			_problem(stream, "a string ended during a punch")
		if thrown != stream.last_index + 1 or landed > thrown:
			_problem(stream, "combo_finished(%d, %d) after punch %d" % [landed, thrown, stream.last_index])
		if not stream.waiting_at_finish.is_empty():
			_problem(stream, "a string ended with %s waiting" % [stream.waiting_at_finish])
		stream.last_index = -1
		stream.combos_finished += 1
		_maybe_command_in_handler(stream))


## Inside a handler, now and then, what a game's handler does: another call.
func _maybe_command_in_handler(stream: Stream) -> void:
	if _frame <= int(_options.frames) and _rng.randf() < 0.1:
		_handler_calls += 1
		_command(stream)


func _hear(stream: Stream, event: String) -> void:
	stream.history.append(event)
	if stream.history.size() > 12:
		stream.history.pop_front()


func _problem(stream: Stream, what: String) -> void:
	_problems.append("%s (frame %d; last events %s)" % [what, _frame, stream.history])
