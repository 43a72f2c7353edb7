"""The app's docks: each edits part of the model and never talks to VTK."""
