"""Bring-up of the actuator node suite: closed-loop core, offline simulation, runner, launch files."""
