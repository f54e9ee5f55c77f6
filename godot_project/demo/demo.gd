## The demo: a character punches a sandbag. Pick a move (the moves the controller's moveset has a policy for, and
## the paper's swing played as `policy`) and a stance, set the noise sigma and how many decisions get noise, and
## punch; keys 1-6 throw the numbered moves (1 jab ... 6 rear uppercut). Every punch starts from the guard pose. A
## left-hand move punches at the mirror image of where the right hand would, so picking a move thrown with the other
## hand hangs the bag at the mirror image of its spot (side negated). "Move bag" hangs it at a random spot of the
## punching hand's reach volume; the arrow keys (side, distance) and Page Up/Down (height) nudge it by 5 cm. The
## running hit rate counts punches with at least one hit.
extends Node3D

## The six moves, numbered as boxing numbers them (keys 1-6).
const MOVES: Array[StringName] = [&"jab", &"cross", &"lead_hook", &"rear_hook", &"lead_uppercut", &"rear_uppercut"]
## The paper's swing: no move, played as the controller's `policy` with the right hand.
const SWING := "res://addons/punch_controller/policies/swing.onnx"
const ADDON_MOVESET := "res://addons/punch_controller/policies/boxing.tres"
const STANCES := ["orthodox (left leads)", "southpaw (right leads)"]
## Seconds between punches when "repeat" is on.
const REPEAT_PAUSE_S := 0.6
## How far one key press moves the bag (m).
const NUDGE_M := 0.05
const SANDBAG_SCENE := preload("res://addons/punch_controller/scenes/punch_sandbag.tscn")

@onready var _character: Node3D = $PunchCharacter
@onready var _sandbag: Node3D = $PunchSandbag
@onready var _bag: RigidBody3D = $PunchSandbag/Bag
@onready var _controller: PunchController = $PunchController
@onready var _move_picker: OptionButton = %Move
@onready var _stance_picker: OptionButton = %Stance
@onready var _sigma: HSlider = %Sigma
@onready var _sigma_value: Label = %SigmaValue
@onready var _noise_decisions: SpinBox = %NoiseDecisions
@onready var _repeat: CheckBox = %Repeat
@onready var _last_punch: Label = %LastPunch
@onready var _impact: Label = %Impact
@onready var _summary: Label = %Summary
@onready var _placement: Label = %Placement
@onready var _hit_rate: Label = %HitRate

## The moveset the controller throws from (its own, else the addon's).
var _moveset: PunchMoveset
## What the move picker's items throw: a move's name, or "" for the swing (`policy`, no move).
var _choices: Array[StringName] = []
## The move thrown by the punch button and "repeat" ("" for the swing).
var _move: StringName = &""
## The hand the bag hangs for: it is mirrored when the punching hand changes.
var _bag_hand: StringName = &"right"
var _hits: Array[String] = []
var _bag_rest: Transform3D
var _punches := 0
var _punches_with_hits := 0
var _repeat_timer := Timer.new()
var _rng := RandomNumberGenerator.new()


func _ready() -> void:
	_bag_rest = _bag.global_transform
	_repeat_timer.one_shot = true
	_repeat_timer.wait_time = REPEAT_PAUSE_S
	_repeat_timer.timeout.connect(punch)
	add_child(_repeat_timer)
	_moveset = _controller.moveset if _controller.moveset != null else load(ADDON_MOVESET)
	for move in _moveset.moves():
		_choices.append(StringName(move))
		_move_picker.add_item(_move_label(move))
	_choices.append(&"")
	_move_picker.add_item("swing (policy)")
	_move_picker.item_selected.connect(func(index): pick_move(_choices[index]))
	for stance in STANCES:
		_stance_picker.add_item(stance)
	_stance_picker.select(_controller.stance)
	_stance_picker.item_selected.connect(pick_stance)
	_sigma.value = _controller.noise_sigma
	_sigma.value_changed.connect(_on_sigma_changed)
	_on_sigma_changed(_sigma.value)
	_noise_decisions.value = _controller.noise_decisions
	_noise_decisions.value_changed.connect(func(value): _controller.noise_decisions = int(value))
	%Punch.pressed.connect(punch)
	%MoveBag.pressed.connect(move_bag_to_random_spot)
	_controller.punch_started.connect(_on_punch_started)
	_controller.hit.connect(_on_hit)
	_controller.punch_finished.connect(_on_punch_finished)
	_use(_choices[0])
	_bag_hand = _hand()
	_show_placement()
	punch.call_deferred()


## Back to the guard pose, the bag at rest, then a new punch of the picked move.
func punch() -> void:
	_repeat_timer.stop()
	_character.reset_pose()
	_bag.global_transform = _bag_rest
	_bag.linear_velocity = Vector3.ZERO
	_bag.angular_velocity = Vector3.ZERO
	_impact.text = "impact: -"
	if _controller.punch(_move):
		_punches += 1


## Picks `move` (a move's name, or "" for the swing) and throws it; the bag is mirrored when its hand is the other.
## A move the moveset has no policy for is not thrown: the panel says so.
func pick_move(move: StringName) -> void:
	if move != &"" and _moveset.policy_for(move) == null:
		_last_punch.text = "%s: no policy for it in the moveset yet" % _move_label(move)
		return
	_use(move)
	_move_picker.select(_choices.find(move))
	_throw_with_bag_on_its_side()


## Sets the controller's stance (PunchController.ORTHODOX or SOUTHPAW) and throws the picked move with it.
func pick_stance(stance: int) -> void:
	_controller.stance = stance
	_stance_picker.select(stance)
	_throw_with_bag_on_its_side()


## Hangs the bag at a random spot of the punching hand's reach volume (in the character's frame).
func move_bag_to_random_spot() -> void:
	var reach := _reach_volume()
	if reach.is_empty():
		return
	var offset := Vector3(_rng.randf_range(reach.side_m.x, reach.side_m.y),
		_rng.randf_range(reach.height_m.x, reach.height_m.y), _rng.randf_range(reach.distance_m.x, reach.distance_m.y))
	_place_bag(offset)


func _unhandled_key_input(event: InputEvent) -> void:
	var key_event := event as InputEventKey
	if key_event == null or not key_event.pressed or key_event.echo:
		return
	var number := key_event.physical_keycode - KEY_1
	if number >= 0 and number < MOVES.size():
		pick_move(MOVES[number])
		return
	var nudges := {KEY_LEFT: Vector3(NUDGE_M, 0, 0), KEY_RIGHT: Vector3(-NUDGE_M, 0, 0), KEY_UP: Vector3(0, 0, NUDGE_M),
		KEY_DOWN: Vector3(0, 0, -NUDGE_M), KEY_PAGEUP: Vector3(0, NUDGE_M, 0), KEY_PAGEDOWN: Vector3(0, -NUDGE_M, 0)}
	if nudges.has(key_event.keycode):
		_place_bag(_bag_offset() + nudges[key_event.keycode])


## The picked move (empty: the swing, played as the controller's `policy`).
func _use(move: StringName) -> void:
	_move = move
	if move == &"":
		_controller.policy = load(SWING)


## The hand the picked move is thrown with in the controller's stance (the swing: the right).
func _hand() -> StringName:
	return &"right" if _move == &"" else PunchController.hand_for(_move, _controller.stance)


## The picked move's reach volume, for the hand the stance gives it (the swing: `policy`'s).
func _reach_volume() -> Dictionary:
	return _controller.reach_volume(_move)


func _throw_with_bag_on_its_side() -> void:
	if _hand() != _bag_hand:
		var offset := _bag_offset()
		_place_bag(Vector3(-offset.x, offset.y, offset.z))
	else:
		punch()


## The bag's rest position in the character's frame (+X its left, +Y up, +Z ahead).
func _bag_offset() -> Vector3:
	return _character.global_transform.affine_inverse() * _bag_rest.origin


## A new sandbag hung at `offset` (its rope's hook is fixed where the scene placed it, so the old one goes).
func _place_bag(offset: Vector3) -> void:
	var sandbag: Node3D = SANDBAG_SCENE.instantiate()
	sandbag.position = _character.transform * offset
	_sandbag.queue_free()
	add_child(sandbag)
	_sandbag = sandbag
	_bag = sandbag.get_node("Bag")
	_bag_rest = _bag.global_transform
	_bag_hand = _hand()
	_controller.target = _bag
	_show_placement()
	punch()


func _show_placement() -> void:
	var offset := _bag_offset()
	_placement.text = "bag: %.2f m ahead, %.2f m high, %.2f m %s" % [offset.z, offset.y, absf(offset.x),
		"left" if offset.x >= 0 else "right"]


## "1 jab", "3 lead hook": the move's number (its key) and name.
func _move_label(move: StringName) -> String:
	return "%d %s" % [MOVES.find(move) + 1, String(move).replace("_", " ")]


func _on_sigma_changed(value: float) -> void:
	_controller.noise_sigma = value
	_sigma_value.text = "%.2f" % value


func _on_punch_started(move: StringName, hand: StringName, _combo_index: int) -> void:
	_hits.clear()
	_last_punch.text = "%s, %s hand: ..." % ["swing" if move == &"" else _move_label(move), hand]


func _on_hit(impulse: float, speed: float, _position: Vector3, body: Node3D, _push: Vector3, hand: StringName,
		_part: StringName, _blocked: bool) -> void:
	_impact.text = "impact: %.1f m/s, %.2f N·s" % [speed, impulse]
	var what := "the bag" if body == _bag else (String(body.name) if body != null else "something since freed")
	_hits.append("%s (%s fist)" % [what, hand])


func _on_punch_finished(metrics: Dictionary) -> void:
	if not (metrics.interrupted and _controller.is_punching()):  # else the next punch has the label
		var move: StringName = metrics.move
		_last_punch.text = "%s, %s hand: %s" % ["swing" if move == &"" else _move_label(move), metrics.hand,
			("hit " + ", ".join(_hits)) if not _hits.is_empty() else ("missed" if not metrics.interrupted else metrics.ended)]
	_summary.text = "punch %d: peak fist speed %.1f m/s, %d hit(s), strongest %.2f N·s" % [
		_punches, metrics.peak_fist_speed_mps, metrics.hits, metrics.strongest_hit_ns]
	if metrics.hits > 0:
		_punches_with_hits += 1
	_hit_rate.text = "hit rate: %d of %d (%.0f%%)" % [_punches_with_hits, _punches, 100.0 * _punches_with_hits / maxi(_punches, 1)]
	if _repeat.button_pressed:
		_repeat_timer.start()
