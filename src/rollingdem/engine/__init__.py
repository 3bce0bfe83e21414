"""The engine: the state's arrays and their layout, the neighbor list, the compiled passes and the step loop, and the backends that run it."""
