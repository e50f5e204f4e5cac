"""`sagebench report`: a static HTML report of a finished run and of agents' predictions, read from their outputs
only (episodes, maps, validate's results, the dataset card's facts, evaluate's scores), written elsewhere."""
