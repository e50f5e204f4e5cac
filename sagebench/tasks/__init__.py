"""The navigation tasks as the closed loop and scoring ask for them: an episode's goal on the map, its success
distance, what its agent observes of the goal and which metrics score it (docs/tasks.md)."""
