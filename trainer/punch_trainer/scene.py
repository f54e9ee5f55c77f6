"""Facts of the addon's character and sandbag scenes that the reward and the simulator both measure against."""

SCENE_ARM_LENGTHS_M = (0.282, 0.337, 0.36)
"""the character scene's own upper arm, forearm (elbow to fist centre) and shoulder width, m"""
SCENE_BAG_RADIUS_M = 0.175
"""the sandbag scene's radius, m (an upright cylinder)"""
SCENE_WAIST_HEIGHT_M = 1.056
"""the character scene's waist joint above its root, m"""
SCENE_SHOULDER_HEIGHT_M = 1.42
"""the character scene's shoulder joints above its root, m"""
GUARD_ELBOW_BEND_DEG = 120.0
"""the elbows' bend in the guard pose, which `angle_elbow_*_extension` counts from (docs/env.md), degrees"""
