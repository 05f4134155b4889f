"""MCAP: the format, its writer and sink, reader, repair, rotation and Foxglove channels."""
