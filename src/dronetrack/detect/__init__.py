"""Detection: clustering the foreground into candidate targets."""
