"""deepphy: the DeepPHY benchmark harness."""
