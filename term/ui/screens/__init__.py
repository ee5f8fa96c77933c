"""The screens and dialogs of the app: each receives what it shows and posts messages up."""
