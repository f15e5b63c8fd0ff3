"""3-D model retargeting with sparse offset statistics (Wu, Li, Wand, Hildebrandt, Jansen, Seidel)."""
