"""The project file: data model, validation, load/save with atomic writes and backup."""
