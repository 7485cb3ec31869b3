"""Commands over the filters alone: replaying a robot log (``main(argv)``; ``scripts/replay_log.py`` and the
``semreloc-replay-log`` console entry point call it)."""
