"""Commands over the envs that are not experiments: the soak test and map building (each has ``main(argv)``;
``scripts/`` and the ``semreloc-*`` console entry points call them)."""
