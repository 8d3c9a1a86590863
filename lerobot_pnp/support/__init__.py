"""Small leaf modules the layers above share, each depending on nothing above ``errors`` / ``presets``.

``cli_config`` (how a command's config is built from defaults, ``--config_path`` and the flags), ``cli_help``
(``--help`` listing every field of a config), ``progress`` (progress bars), ``slurm_fields`` (SLURM option
checks) and ``markdown_text`` (user text placed into generated Markdown as literal text). This ``__init__``
imports nothing.
"""
