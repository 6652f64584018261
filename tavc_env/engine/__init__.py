"""The arena engine: pymunk bodies and walls (`world`), the robots' reactive controller
(`navigation`), stations and the task cycle (`tasks`), and the tick-by-tick loop that joins them
(`simulation`). It knows circuits, tasks and time, and nothing of observations, rewards or agents."""
