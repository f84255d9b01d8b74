"""brush_env: toothbrush DFM dynamics engine and Gymnasium environments."""
