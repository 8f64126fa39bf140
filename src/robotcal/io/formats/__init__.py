"""File formats robotcal reads and writes: capture CSV, tracker exports, trajectories, parameter JSON, Monte Carlo
draws, orientations, exports to other tools."""
