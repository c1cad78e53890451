"""Pictures and videos of robots: offscreen MuJoCo rendering of a design's pose or of
recorded rollouts, into PNG, GIF or MP4 (`video`)."""
