"""The launch templates fleet ships: installed as the package `fleet.templates`, so an installed
fleet finds them where its code is (fleet.expand.templating.builtin_template_dirs)."""
