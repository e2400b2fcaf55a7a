"""The command line's commands, a module per family: each has ``register(commands)``, which adds its
subcommands (and their handlers) to :func:`besman.cli.build_parser`'s parser."""
