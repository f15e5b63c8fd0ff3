"""A tiny method used only by the framework tests: copies or inverts an image."""
