"""What every room of ``agents`` uses: CLI errors and entry point (:mod:`.cli`), the
benchmark's success rule and summaries (:mod:`.metrics`), environment construction, the
``env_wrapper`` allow-list and seeded goal sets (:mod:`.env_factory`)."""
