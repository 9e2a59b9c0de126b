"""Demo scenes and the demos the CLI runs (``twinsense demo NAME``)."""
