"""The browser viewer: a local page that decodes a .csgs in a Web Worker with the JavaScript
receiver (``csgs_codec/js``) and renders it with the vendored PlayCanvas engine.

``server.ViewerServer`` serves the page, the receiver's modules, the frozen tables and one
scene file (answering HTTP Range requests, so the page reads only the layers it shows).
"""
