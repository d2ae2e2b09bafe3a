"""Table III of the paper: YuMi picks out of 30, trained models in the loop (gva reproduce real)."""
