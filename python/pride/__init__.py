"""pride."""
