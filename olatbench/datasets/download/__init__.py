"""Fetch, verify and lay out the official OLAT datasets (stdlib + tqdm; no torch).

`sources` holds where each scene is published, as data; `transfer` downloads resumably;
`archives` unpacks safely; `manifest` records and checks sha256 hashes; `fetch`
puts them together for ``olatbench datasets download``.
"""
