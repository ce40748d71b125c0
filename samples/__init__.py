"""The sample lake trial: its simulator and its generated logs."""
