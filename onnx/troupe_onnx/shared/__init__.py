"""What the families share: transformer layers, strict checkpoint loading, the portable noise
generator and the exporter's common parts."""
