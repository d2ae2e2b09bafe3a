"""Table II of the paper: position error of every model in the simulator (``gva reproduce sim``)."""
