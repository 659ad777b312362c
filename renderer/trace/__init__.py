"""The numpy trace shared by the planner and the prediction (no Mitsuba): geometry and the grating equation."""
