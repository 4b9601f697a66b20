"""Process supervisor and runner, main job, benchmark and middleware-floor nodes."""
