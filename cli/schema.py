"""``synthkit schema METHOD``: the JSON Schema of METHOD's config, for editors and the YAML language server."""

from __future__ import annotations

import click

from synthkit.methods import available_methods


@click.command(name="schema")
@click.argument("method", type=click.Choice(available_methods()))
def command(method: str) -> None:
    """Print the JSON Schema (draft 2020-12) of METHOD's config on stdout.

    Point the YAML language server at it with a first line
    `# yaml-language-server: $schema=path/to/schema.json`.
    """
    import json

    from synthkit.methods.rooms import config_module

    schema = config_module(method).CONFIG.model_json_schema()
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = f"synthkit {method} config"
    click.echo(json.dumps(schema, indent=2))
