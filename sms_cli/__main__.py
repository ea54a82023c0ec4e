from sms_cli.cli import main

main()
