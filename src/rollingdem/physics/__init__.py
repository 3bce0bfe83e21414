"""The physics: contact sub-models, the bond law, wall and mesh contact geometry, time-step criteria; pure compiled functions and the classes that declare their parameters."""
