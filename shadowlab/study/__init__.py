"""Studies (DESIGN §12–13): a suite of scenes × technique configurations, run in parallel and cached, drawn as one comparison."""
