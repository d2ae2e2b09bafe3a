"""Robot descriptions: URDF files and the small facts a planner needs about them."""
