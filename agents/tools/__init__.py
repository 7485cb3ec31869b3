"""Commands over envs and policies that are not experiments: the demo (``main(argv)``; ``scripts/demo.py`` and
the ``semreloc-demo`` console entry point call it)."""
