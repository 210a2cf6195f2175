"""Studies (docs/contracts.md#study-directory): a suite of scenes × technique configurations, run in parallel and cached, drawn as one comparison."""
