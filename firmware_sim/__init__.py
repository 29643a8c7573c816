"""firmware_sim: the simulated motor/furnace CAN node of the rod mill."""
