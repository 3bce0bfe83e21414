"""What a user builds: materials, particles and their insertion, walls, boundaries, bonds, and the Simulation."""
