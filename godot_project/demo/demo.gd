## The demo: a character punches a sandbag with a policy trained by `punch train`. Pick a style, set the noise
## sigma and how many decisions get noise, and punch; every punch starts from the guard pose. "Move bag" hangs
## the bag at a random spot of the policy's reach volume; the arrow keys (side, distance) and Page Up/Down
## (height) nudge it by 5 cm. The running hit rate counts punches with at least one hit.
extends Node3D

const STYLES := ["straight", "hook", "swing"]
## Seconds between punches when "repeat" is on.
const REPEAT_PAUSE_S := 0.6
## How far one key press moves the bag (m).
const NUDGE_M := 0.05
const SANDBAG_SCENE := preload("res://addons/punch_controller/scenes/punch_sandbag.tscn")

@onready var _character: Node3D = $PunchCharacter
@onready var _sandbag: Node3D = $PunchSandbag
@onready var _bag: RigidBody3D = $PunchSandbag/Bag
@onready var _controller: Node = $PunchController
@onready var _style: OptionButton = %Style
@onready var _sigma: HSlider = %Sigma
@onready var _sigma_value: Label = %SigmaValue
@onready var _noise_decisions: SpinBox = %NoiseDecisions
@onready var _repeat: CheckBox = %Repeat
@onready var _impact: Label = %Impact
@onready var _summary: Label = %Summary
@onready var _placement: Label = %Placement
@onready var _hit_rate: Label = %HitRate

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
	for style in STYLES:
		_style.add_item(style)
	_style.item_selected.connect(func(index): _controller.policy = load(_policy_path(STYLES[index])))
	_sigma.value = _controller.noise_sigma
	_sigma.value_changed.connect(_on_sigma_changed)
	_on_sigma_changed(_sigma.value)
	_noise_decisions.value = _controller.noise_decisions
	_noise_decisions.value_changed.connect(func(value): _controller.noise_decisions = int(value))
	%Punch.pressed.connect(punch)
	%MoveBag.pressed.connect(move_bag_to_random_spot)
	_show_placement()
	_controller.hit.connect(_on_hit)
	_controller.punch_finished.connect(_on_punch_finished)
	punch.call_deferred()


## Back to the guard pose, the bag at rest, then a new punch.
func punch() -> void:
	_repeat_timer.stop()
	_character.reset_pose()
	_bag.global_transform = _bag_rest
	_bag.linear_velocity = Vector3.ZERO
	_bag.angular_velocity = Vector3.ZERO
	_impact.text = "impact: -"
	if _controller.punch():
		_punches += 1


## Hangs the bag at a random spot of the policy's reach volume (in the character's frame).
func move_bag_to_random_spot() -> void:
	var reach: Dictionary = _controller.reach_volume()
	if reach.is_empty():
		return
	var offset := Vector3(_rng.randf_range(reach.side_m.x, reach.side_m.y),
		_rng.randf_range(reach.height_m.x, reach.height_m.y), _rng.randf_range(reach.distance_m.x, reach.distance_m.y))
	_place_bag(offset)


func _unhandled_key_input(event: InputEvent) -> void:
	if not event.is_pressed():
		return
	var nudges := {KEY_LEFT: Vector3(NUDGE_M, 0, 0), KEY_RIGHT: Vector3(-NUDGE_M, 0, 0), KEY_UP: Vector3(0, 0, NUDGE_M),
		KEY_DOWN: Vector3(0, 0, -NUDGE_M), KEY_PAGEUP: Vector3(0, NUDGE_M, 0), KEY_PAGEDOWN: Vector3(0, -NUDGE_M, 0)}
	var key: Key = (event as InputEventKey).keycode
	if nudges.has(key):
		_place_bag(_bag_offset() + nudges[key])


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
	_controller.target = _bag
	_show_placement()
	punch()


func _show_placement() -> void:
	var offset := _bag_offset()
	_placement.text = "bag: %.2f m ahead, %.2f m high, %.2f m %s" % [offset.z, offset.y, absf(offset.x),
		"left" if offset.x >= 0 else "right"]


func _policy_path(style: String) -> String:
	return "res://addons/punch_controller/policies/%s.onnx" % style


func _on_sigma_changed(value: float) -> void:
	_controller.noise_sigma = value
	_sigma_value.text = "%.2f" % value


func _on_hit(impulse: float, speed: float, _position: Vector3, _body: Node3D, _push: Vector3, _hand: StringName) -> void:
	_impact.text = "impact: %.1f m/s, %.2f N·s" % [speed, impulse]


func _on_punch_finished(metrics: Dictionary) -> void:
	_summary.text = "punch %d: peak fist speed %.1f m/s, %d hit(s), strongest %.2f N·s" % [
		_punches, metrics.peak_fist_speed_mps, metrics.hits, metrics.strongest_hit_ns]
	if metrics.hits > 0:
		_punches_with_hits += 1
	_hit_rate.text = "hit rate: %d of %d (%.0f%%)" % [_punches_with_hits, _punches, 100.0 * _punches_with_hits / maxi(_punches, 1)]
	if _repeat.button_pressed:
		_repeat_timer.start()
