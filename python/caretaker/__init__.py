"""caretaker."""
